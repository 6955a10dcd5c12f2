#!/usr/bin/env python3
"""Lists the module dependencies of the Rust crate (native/src) and of the Python package (akd_ros/) and fails
when they form a cycle.

A dependency is a path one module names in its code: `crate::a::b`, `super::x`, `self::x` in Rust (use trees with
braces expanded), `import akd_ros.x` / `from akd_ros.x import y` / relative imports in Python. Comments, doc
comments and `#[cfg(test)]` modules do not count: docs may link anywhere, and tests may use anything beside or
below them.

Two rules are checked, because a parent module declares its children and re-exports from them (containment, not
a layer):
- among the top-level modules of each tree (each with its children folded in), no cycle;
- among the sibling modules of each directory (each with its own children folded in), no cycle.

Usage: scripts/module_deps.py [--list]   (--list prints every module's dependencies as well)
Exits 1 and names each cycle when one is found.
"""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RUST_SRC = ROOT / "native" / "src"
PYTHON_PACKAGE = ROOT / "akd_ros"
IDENT = r"[A-Za-z_][A-Za-z0-9_]*"


def rust_module_of(path: Path) -> tuple[str, ...]:
    """The module path of a source file: src/a/b.rs and src/a/b/mod.rs are ("a", "b"); lib.rs is ()."""
    parts = list(path.relative_to(RUST_SRC).with_suffix("").parts)
    if parts[-1] in ("mod", "lib"):
        parts.pop()
    return tuple(parts)


def strip_rust(text: str) -> str:
    """The code without comments, string literals or `#[cfg(test)]` modules."""
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.DOTALL)
    text = re.sub(r'r#*"(?:.|\n)*?"#*', '""', text)
    text = re.sub(r'"(?:\\.|[^"\\])*"', '""', text)
    text = re.sub(r"'(?:\\.|[^'\\])'", "' '", text)
    text = re.sub(r"//[^\n]*", "", text)
    while found := re.search(r"#\[cfg\(test\)\]\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+" + IDENT + r"\s*\{", text):
        depth, end = 0, found.end() - 1
        for end in range(found.end() - 1, len(text)):
            depth += {"{": 1, "}": -1}.get(text[end], 0)
            if depth == 0:
                break
        text = text[: found.start()] + text[end + 1 :]
    return text


def expand_use_tree(tree: str) -> list[str]:
    """`a::{b, c::{d, e}}` -> ["a::b", "a::c::d", "a::c::e"]."""
    tree = re.sub(r"\s+", "", tree)
    brace = tree.find("{")
    if brace < 0:
        return [tree]
    prefix, inner = tree[:brace], tree[brace + 1 : tree.rindex("}")]
    items, depth, start = [], 0, 0
    for i, char in enumerate(inner):
        depth += {"{": 1, "}": -1}.get(char, 0)
        if char == "," and depth == 0:
            items.append(inner[start:i])
            start = i + 1
    items.append(inner[start:])
    return [path for item in items if item for path in expand_use_tree(prefix + item)]


def rust_paths(code: str) -> list[str]:
    """Every path the code names that starts at crate, super or self."""
    paths = []
    for found in re.finditer(r"\buse\s+([^;]+);", code):
        paths += expand_use_tree(found.group(1))
    code = re.sub(r"\buse\s+[^;]+;", "", code)
    paths += re.findall(rf"\b(?:crate|super|self)(?:::{IDENT})+", code)
    return [p for p in paths if re.match(r"(crate|super|self)::", p)]


def resolve_rust(module: tuple[str, ...], path: str, modules: set) -> tuple[str, ...]:
    """The deepest existing module a path names, seen from `module`."""
    parts = path.split("::")
    if parts[0] == "crate":
        base, rest = (), parts[1:]
    else:
        # In a/b.rs and in a/b/mod.rs alike, `self` is a::b and `super` is a.
        base = module
        while parts and parts[0] in ("super", "self"):
            if parts.pop(0) == "super":
                base = base[:-1]
        rest = parts
    target = base
    for part in rest:
        if (*base, part) in modules or (*target, part) in modules:
            target = (*target, part)
        else:
            break
    return target


def tracked(directory: Path, pattern: str) -> list[Path]:
    """The files git tracks below `directory` (generated ones, such as akd_ros/msg, are not the project's
    modules), or all of them outside a git checkout."""
    listed = subprocess.run(["git", "ls-files", "-z", "--", pattern], cwd=directory, capture_output=True)
    if listed.returncode != 0:
        return sorted(directory.rglob(pattern))
    return sorted(directory / name for name in listed.stdout.decode().split("\0") if name)


def rust_graph() -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    files = tracked(RUST_SRC, "*.rs")
    modules = {rust_module_of(f) for f in files}
    graph: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    for f in files:
        module = rust_module_of(f)
        graph[module]
        for path in rust_paths(strip_rust(f.read_text())):
            target = resolve_rust(module, path, modules)
            if target not in (module, ()):
                graph[module].add(target)
    return graph


def python_graph() -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    files = tracked(PYTHON_PACKAGE, "*.py")
    root = PYTHON_PACKAGE.name

    def module_of(f: Path) -> tuple[str, ...]:
        parts = (root, *f.relative_to(PYTHON_PACKAGE).with_suffix("").parts)
        return parts[:-1] if parts[-1] == "__init__" else parts

    # The extension module is the Rust crate's layer below, a module of the package like the others.
    modules = {module_of(f) for f in files} | {(root, "_native")}
    graph: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    for f in files:
        module = module_of(f)
        package = module if f.name == "__init__.py" else module[:-1]
        graph[module]
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            names: list[tuple[str, ...]] = []
            if isinstance(node, ast.Import):
                names = [tuple(a.name.split(".")) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else ()
                stem = base + tuple((node.module or "").split(".")) if node.module else base
                names = [(*stem, a.name) for a in node.names] + [stem]
            for name in names:
                while name and name not in modules:
                    name = name[:-1]
                if name and name != module and name[0] == root:
                    graph[module].add(name)
    return graph


def fold(graph: dict, depth_of: tuple[str, ...]) -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    """The graph among the children of `depth_of`, each child standing for itself and everything below it; edges
    leaving that directory and edges to or from the directory's own module are left out."""
    level = len(depth_of) + 1
    folded: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    for source, targets in graph.items():
        if len(source) < level or source[: level - 1] != depth_of:
            continue
        for target in targets:
            if len(target) < level or target[: level - 1] != depth_of:
                continue
            a, b = source[:level], target[:level]
            folded[a]
            if a != b:
                folded[a].add(b)
    return folded


def cycles(graph: dict) -> list[list]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def check(name: str, graph: dict, root: tuple[str, ...], show: bool) -> list[str]:
    problems = []
    directories = sorted({m[:i] for m in graph for i in range(len(root), len(m))})
    for directory in directories:
        for component in cycles(fold(graph, directory)):
            where = "::".join(directory) or "the crate"
            problems.append(
                f"{name}: cycle among the modules of {where}: " + " <-> ".join("::".join(m) for m in component)
            )
    if show:
        for module in sorted(graph):
            targets = ", ".join("::".join(t) for t in sorted(graph[module])) or "-"
            print(f"{name} {'::'.join(module) or 'lib'} -> {targets}")
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true", help="print every module's dependencies")
    args = parser.parse_args()
    problems = check("rust", rust_graph(), (), args.list) + check("python", python_graph(), ("akd_ros",), args.list)
    for problem in problems:
        print(f"module_deps: {problem}", file=sys.stderr)
    if not problems:
        print("module_deps: no cycles (Rust crate native/src and Python package akd_ros)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
