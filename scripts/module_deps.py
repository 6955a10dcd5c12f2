#!/usr/bin/env python3
"""Checks the layers of the Rust crate (native/src) and of the Python package (akd_ros/): fails on a module cycle or
on a dependency that points up a layer.

A dependency is a path one module names in its code: `crate::a::b`, `super::x`, `self::x` in Rust, read by a real
parser (syn, through the small tool in scripts/module-deps: use trees expanded, paths in macros counted, strings,
comments, doc comments, attributes and `#[cfg(test)]` items passed over), and `import akd_ros.x` /
`from akd_ros.x import y` / relative imports in Python (read by `ast`). Docs may link anywhere, and tests may use
anything.

Three rules, because a parent module declares its children and re-exports from them (containment, not a layer):
- among the top-level modules of each tree (each with its children folded in), no cycle;
- among the sibling modules of each directory (each with its own children folded in), no cycle;
- a top-level module depends only on modules of its own layer or of the layers below it (`RUST_LAYERS`,
  `PYTHON_LAYERS`, lowest first), and never on a module declared apart from it (the virtual AKD and the master).

Usage: scripts/module_deps.py [--list] [--root DIR]   (--list prints every module's dependencies as well; --root
checks the tree below DIR, holding native/src and akd_ros, instead of this repository)
Exits 1 and names each cycle and each upward dependency found.
"""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

TOOL = Path(__file__).resolve().parent / "module-deps"
PYTHON_ROOT = "akd_ros"

RUST_LAYERS: list[set[str]] = [
    {"wire_code"},
    # The codecs and the drive's knowledge: pure, no I/O; the master and the virtual AKD both use them. Each
    # raises its own error (frame::FrameError, mailbox::MailboxError, ...).
    {
        "frame",
        "registers",
        "sii",
        "al",
        "mailbox",
        "coe",
        "eoe",
        "foe",
        "pdo",
        "objects",
        "dc",
        "ds402",
        "akd_fault",
        "io",
        "scaling",
        "trajectory",
        "link_spec",
        "setting",
        "bag_file",
        "ros_msgs",
    },
    # The umbrella error over every layer's own errors, with their Froms.
    {"error"},
    # I/O: the links that move frames, and the bag writer's files.
    {"link", "bag_writer"},
    # The virtual AKD beside the master: the same codecs and links, never each other's state.
    {"master", "sim"},
    {"cycle"},
    # What the node needs from the cycle, off the cycle thread: its records and its feed of messages.
    {"node"},
    {"python"},
]
"""The crate's top-level modules by layer, lowest first."""
RUST_APART = {frozenset({"master", "sim"})}
"""Pairs of top-level modules of one layer that must not depend on each other."""
PYTHON_LAYERS: list[set[str]] = [
    {"_native"},
    {"units", "privilege", "tap"},
    {"bus"},
    {"axis"},
    {"params", "recorder", "eoe_bridge", "zenoh"},
    {"node"},
    {"top"},
    {"cli"},
]
"""The package's top-level modules (below akd_ros) by layer, lowest first."""


def rust_module_of(src: Path, path: Path) -> tuple[str, ...]:
    """The module path of a source file: src/a/b.rs and src/a/b/mod.rs are ("a", "b"); lib.rs is ()."""
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] in ("mod", "lib"):
        parts.pop()
    return tuple(parts)


def rust_paths(files: list[Path]) -> dict[Path, list[str]]:
    """Every path each file's code names that starts at crate, super or self, as the syn-based tool in
    scripts/module-deps reads them (built on first use with cargo)."""
    subprocess.run(
        ["cargo", "build", "--quiet", "--release", "--manifest-path", str(TOOL / "Cargo.toml")],
        check=True,
    )
    listed = subprocess.run(
        [str(TOOL / "target" / "release" / "module-deps"), *map(str, files)], capture_output=True, text=True
    )
    if listed.returncode != 0:
        raise SystemExit(f"module_deps: {listed.stderr.strip()}")
    paths: dict[Path, list[str]] = {f: [] for f in files}
    for line in listed.stdout.splitlines():
        name, path = line.split("\t")
        paths[Path(name)].append(path)
    return paths


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


def rust_graph(src: Path) -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    files = tracked(src, "*.rs")
    modules = {rust_module_of(src, f) for f in files}
    graph: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    for f, paths in rust_paths(files).items():
        module = rust_module_of(src, f)
        graph[module]
        for path in paths:
            target = resolve_rust(module, path, modules)
            if target not in (module, ()):
                graph[module].add(target)
    return graph


def python_graph(package: Path) -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    files = tracked(package, "*.py")
    root = package.name

    def module_of(f: Path) -> tuple[str, ...]:
        parts = (root, *f.relative_to(package).with_suffix("").parts)
        return parts[:-1] if parts[-1] == "__init__" else parts

    # The extension module is the Rust crate's layer below, a module of the package like the others.
    modules = {module_of(f) for f in files} | {(root, "_native")}
    graph: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    for f in files:
        module = module_of(f)
        package_of = module if f.name == "__init__.py" else module[:-1]
        graph[module]
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            names: list[tuple[str, ...]] = []
            if isinstance(node, ast.Import):
                names = [tuple(a.name.split(".")) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = package_of[: len(package_of) - node.level + 1] if node.level else ()
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


def layer_problems(name: str, graph: dict, root: tuple[str, ...], layers: list[set[str]], apart: set) -> list[str]:
    """Each dependency of a top-level module (below `root`) on a module of a higher layer or on one declared apart
    from it, and each top-level module no layer names."""
    level = len(root)
    rank = {module: i for i, layer in enumerate(layers) for module in layer}
    problems = []
    for source, targets in sorted(graph.items()):
        if len(source) <= level:
            continue
        a = source[level]
        if a not in rank:
            problems.append(f"{name}: module {'::'.join(source)} is in no layer; add it to the table")
            continue
        for target in sorted(targets):
            if len(target) <= level or target[level] == a:
                continue
            b = target[level]
            if b in rank and (rank[b] > rank[a] or frozenset({a, b}) in apart):
                why = "a layer above it" if rank[b] > rank[a] else "a module kept apart from it"
                problems.append(f"{name}: {'::'.join(source)} depends on {'::'.join(target)}, {why}")
    return problems


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
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent, help="the tree to check")
    args = parser.parse_args()
    rust, python = rust_graph(args.root / "native" / "src"), python_graph(args.root / PYTHON_ROOT)
    problems = (
        check("rust", rust, (), args.list)
        + layer_problems("rust", rust, (), RUST_LAYERS, RUST_APART)
        + check("python", python, (PYTHON_ROOT,), args.list)
        + layer_problems("python", python, (PYTHON_ROOT,), PYTHON_LAYERS, set())
    )
    for problem in problems:
        print(f"module_deps: {problem}", file=sys.stderr)
    if not problems:
        print("module_deps: no cycles, no dependency up a layer (Rust crate native/src and Python package akd_ros)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
