#!/usr/bin/env python3
"""Checks the layers of the Rust crate (native/src) and of the Python package (akd_ros/): fails on a module cycle or
on a dependency that points up a layer.

A dependency is a path one module names in its code: `crate::a::b`, `super::x`, `self::x` in Rust, read by a real
parser (syn, through the small tool in scripts/module-deps: use trees expanded, paths in macros counted, strings,
comments, doc comments, attributes and `#[cfg(test)]` items passed over), and `import akd_ros.x` /
`from akd_ros.x import y` / relative imports in Python (read by `ast`). Docs may link anywhere, and tests may use
anything.

Four rules, because a parent module declares its children and re-exports from them (containment, not a layer):
- the modules a layer table names (`RUST_LAYERS`, `PYTHON_LAYERS`, lowest first) are the units of the layers: a
  top-level module, or one inside a product's folder where the folder spans layers (the EtherCAT layer's codecs, links
  and master); every module belongs to the deepest unit that contains it, and among the units (each with its children
  folded in) there is no cycle;
- among the sibling modules of each directory below the top (each with its own children folded in), no cycle;
- a unit depends only on units of its own layer or of the layers below it;
- a module never depends on a module `RUST_APART` keeps from it: the EtherCAT layer on the drive profile (or on the
  virtual AKD, the cycle, the ROS side, the bindings), the virtual AKD on the master or on what uses it;
- the EtherCAT layer's code names no object of a device (`DEVICE_OBJECTS`): no hex literal of four digits between
  0x2000 and 0x9FFF but a single bit (a mask) or one of `NOT_OBJECTS`, so that a drive's object it writes (0x6060,
  0x60C2, FBUS.PARAM02's 0x3E02) is seen even where it imports nothing of the drive profile.

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
    {"wire_code", "spelling"},
    # The codecs and the drive's knowledge: pure, no I/O; the master and the virtual AKD both use them. Each raises its
    # own error (frame::FrameError, mailbox::MailboxError, ...). A product's folder holds only declarations.
    {
        "setting",
        "ethercat",
        "ethercat::frame",
        "ethercat::registers",
        "ethercat::sii",
        "ethercat::al",
        "ethercat::mailbox",
        "ethercat::coe",
        "ethercat::eoe",
        "ethercat::foe",
        "ethercat::dc",
        "ethercat::pdo",
        "ethercat::device",
        "ethercat::link_spec",
        "drive",
        "drive::ds402",
        "drive::identity",
        "drive::pdo",
        "drive::objects",
        "drive::scaling",
        "drive::sync",
        "drive::akd_fault",
        "drive::io",
        "drive::trajectory",
        "ros::msgs",
        "ros::bag_file",
    },
    # The umbrella error over every layer's own errors, with their Froms.
    {"error"},
    # I/O: the links that move frames, and the bag writer's files.
    {"ethercat::link", "ros::bag_writer"},
    # The virtual AKD beside the master: the same codecs and links, never each other's state.
    {"ethercat::master", "sim"},
    # What the drive profile does to an AKD through the master.
    {"drive::akd"},
    {"cycle"},
    # What the node needs from the cycle, off the cycle thread: its records and its feed of messages.
    {"ros"},
    {"python"},
]
"""The crate's units by layer, lowest first."""
RUST_APART: dict[str, set[str]] = {
    "ethercat": {"drive", "sim", "cycle", "ros", "python"},
    "sim": {"ethercat::master", "drive::akd", "cycle", "ros", "python"},
}
"""Modules (with their children) and the modules (with theirs) they must never depend on, whatever the layers: the
EtherCAT layer knows no AKD, and the virtual AKD shares the master's codecs and links, never its state."""
OBJECTS_UNNAMED = "ethercat"
"""The module (with its children) whose code names no object of a device."""
DEVICE_OBJECTS = range(0x2000, 0xA000)
"""CoE object indices of a device: its manufacturer's (0x2000-0x5FFF) and its profiles' (0x6000-0x9FFF, CiA 402's
among them). A master names only those of the communication area (0x1000-0x1FFF: identity, PDO mapping and
assignment, sync manager parameters)."""
NOT_OBJECTS = {0x88A4: "the EtherCAT EtherType"}
"""Four-digit hex numbers of the EtherCAT layer in `DEVICE_OBJECTS`' range that are no object."""
PYTHON_LAYERS: list[set[str]] = [
    {"_native"},
    {"units", "privilege", "tap"},
    {"bus"},
    {"axis"},
    {"device"},
    {"params", "recorder", "eoe_bridge", "zenoh"},
    {"node"},
    {"top", "access"},
    {"cli"},
]
"""The package's units (top-level modules below akd_ros) by layer, lowest first."""


def rust_module_of(src: Path, path: Path) -> tuple[str, ...]:
    """The module path of a source file: src/a/b.rs and src/a/b/mod.rs are ("a", "b"); lib.rs is ()."""
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] in ("mod", "lib"):
        parts.pop()
    return tuple(parts)


def rust_paths(files: list[Path]) -> dict[Path, list[str]]:
    """Every path each file's code names that starts at crate, super or self, and every hex literal it writes
    (`=0x6060`), as the syn-based tool in scripts/module-deps reads them (built on first use with cargo)."""
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


def rust_graph(src: Path) -> tuple[dict[tuple[str, ...], set[tuple[str, ...]]], list[str]]:
    """The crate's module graph, and each object of a device named where `OBJECTS_UNNAMED` names none."""
    files = tracked(src, "*.rs")
    modules = {rust_module_of(src, f) for f in files}
    graph: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    problems = []
    for f, paths in rust_paths(files).items():
        module = rust_module_of(src, f)
        graph[module]
        for path in paths:
            if path.startswith("="):
                if within(module, {OBJECTS_UNNAMED}) and (number := device_object(path[1:])) is not None:
                    problems.append(
                        f"rust: {'::'.join(module)} names 0x{number:04X}, an object of a device (0x2000-0x9FFF): "
                        "the profile's to write, not the EtherCAT layer's"
                    )
                continue
            target = resolve_rust(module, path, modules)
            if target not in (module, ()):
                graph[module].add(target)
    return graph, list(dict.fromkeys(problems))


def device_object(literal: str) -> int | None:
    """The object index a hex literal (`0x6060`, `0x6060u16`) writes, if it is four digits in `DEVICE_OBJECTS` and
    neither a single bit nor one of `NOT_OBJECTS`."""
    digits = literal[2:].split("u")[0].split("i")[0]
    if len(digits) != 4 or "_" in digits:
        return None
    number = int(digits, 16)
    single_bit = number & (number - 1) == 0
    return number if number in DEVICE_OBJECTS and not single_bit and number not in NOT_OBJECTS else None


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


def unit_of(module: tuple[str, ...], root: tuple[str, ...], units: set[tuple[str, ...]]) -> tuple[str, ...] | None:
    """The deepest unit (below `root`) that holds `module`, if any."""
    relative = module[len(root) :]
    return next((relative[:n] for n in range(len(relative), 0, -1) if relative[:n] in units), None)


def within(module: tuple[str, ...], names: set[str]) -> str | None:
    """The one of `names` that `module` is or lies inside, if any."""
    return next((n for n in sorted(names) if module[: len(n.split("::"))] == tuple(n.split("::"))), None)


def layer_problems(
    name: str, graph: dict, root: tuple[str, ...], layers: list[set[str]], apart: dict[str, set[str]]
) -> list[str]:
    """Each dependency of a unit (below `root`) on a unit of a higher layer, each dependency of a module on one kept
    apart from it, each cycle among the units, and each module in no unit."""
    level = len(root)
    rank = {tuple(unit.split("::")): i for i, layer in enumerate(layers) for unit in layer}
    known = set(rank)
    units: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    problems = []
    for source, targets in sorted(graph.items()):
        if len(source) <= level:
            continue
        a = unit_of(source, root, known)
        if a is None:
            problems.append(f"{name}: module {'::'.join(source)} is in no layer; add it to the table")
            continue
        units[a]
        relative = source[level:]
        kept = next(((k, v) for k, v in apart.items() if within(relative, {k})), None)
        for target in sorted(targets):
            b = unit_of(target, root, known)
            if kept and within(target[level:], kept[1]):
                problems.append(
                    f"{name}: {'::'.join(source)} depends on {'::'.join(target)}, a module kept apart from it"
                )
            elif b is not None and b != a and rank[b] > rank[a]:
                problems.append(f"{name}: {'::'.join(source)} depends on {'::'.join(target)}, a layer above it")
            if b is not None and b != a:
                units[a].add(b)
    for component in cycles(units):
        problems.append(
            f"{name}: cycle among the modules of {'::'.join(root) or 'the crate'}: "
            + " <-> ".join("::".join((*root, *m)) for m in component)
        )
    return problems


def check(name: str, graph: dict, root: tuple[str, ...], show: bool) -> list[str]:
    """Each cycle among the sibling modules of a directory below the top (the top's are the layers' units)."""
    problems = []
    directories = sorted({m[:i] for m in graph for i in range(len(root) + 1, len(m))})
    for directory in directories:
        for component in cycles(fold(graph, directory)):
            problems.append(
                f"{name}: cycle among the modules of {'::'.join(directory)}: "
                + " <-> ".join("::".join(m) for m in component)
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
    (rust, objects), python = rust_graph(args.root / "native" / "src"), python_graph(args.root / PYTHON_ROOT)
    problems = (
        objects
        + check("rust", rust, (), args.list)
        + layer_problems("rust", rust, (), RUST_LAYERS, RUST_APART)
        + check("python", python, (PYTHON_ROOT,), args.list)
        + layer_problems("python", python, (PYTHON_ROOT,), PYTHON_LAYERS, {})
    )
    for problem in problems:
        print(f"module_deps: {problem}", file=sys.stderr)
    if not problems:
        print(
            "module_deps: no cycles, no dependency up a layer, no device's object in the EtherCAT layer (Rust crate "
            "native/src and Python package akd_ros)"
        )
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
