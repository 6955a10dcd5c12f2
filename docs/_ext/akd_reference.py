"""The generated part of the reference: written at each build into docs/_generated/ from the code's own declarations,
and included by the reference pages, so that it cannot drift from the code.

- parameters.md: `akd_ros.params.SCHEMA` (name, type, default, range or allowed values, description), by group;
- topics.md, services.md, actions.md: what the node's parts declare (`akd_ros.node.interface.declared`), on a node
  of joints and on a node of one joint, each with its description from reference/node_interface.yaml (a door without a
  description, or a description of a door the node lacks, fails the build);
- messages.md: every definition in msg/, srv/ and action/, with the topics, services and actions that carry it;
- tools.md: each command-line tool's --help, as its console script prints it.

`tests/test_docs_reference.py` compares the same lists with a running node's.
"""

from __future__ import annotations

import importlib.metadata
import math
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import yaml
from sphinx.errors import ExtensionError

ROOT = Path(__file__).resolve().parents[2]
GENERATED = ROOT / "docs" / "_generated"
DESCRIPTIONS = ROOT / "docs" / "reference" / "node_interface.yaml"
INTERFACE_DIRS = ("msg", "srv", "action")
EXAMPLE_JOINTS = ("joint_a", "joint_b")
"""The joints of the node of joints the reference lists; joint_a stands for every joint (~/<joint>/)."""
JOINT = "<joint>"
EXAMPLE_DEVICE = "device_a"
"""The device of the nodes the reference lists, standing for every device (~/<device>/)."""
DEVICE = "<device>"
_TYPE_NAMES = {str: "string", list: "string[]", int: "integer", float: "double", bool: "bool"}
_GROUP_TITLES = {
    "node": "The node and its bus",
    "joint": "Each joint: drive, mode, units, faults",
    "devices": "Each device beside the drives",
    "mapping": "Each joint: PDO mapping",
    "limits": "Each joint: command limits",
    "latch": "Each joint: latches",
    "eoe": "Ethernet over EtherCAT",
    "rt": "Real-time",
    "record": "Recording",
    "live_view": "Live view (Foxglove)",
    "zenoh": "Zenoh",
}


def _cell(text: object) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _value(value: object) -> str:
    """A default as a parameters file spells it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and math.isinf(value):
        return ".inf" if value > 0 else "-.inf"
    if isinstance(value, str):
        return f"'{value}'" if value == "" else value
    return str(value)


def parameter_groups() -> list[tuple[str, list]]:
    """SCHEMA's parameters by group: a dotted name's prefix, else whether each joint has it; in schema order."""
    from akd_ros.params import DEVICE_SPECS, SCHEMA

    groups: dict[str, list] = {}
    for spec in SCHEMA:
        key = spec.name.split(".")[0] if "." in spec.name else ("joint" if spec.per_joint else "node")
        groups.setdefault(key, []).append(spec)
    groups["devices"] = [replace(spec, name=f"devices.{DEVICE}.{spec.name}") for spec in DEVICE_SPECS]
    return list(groups.items())


def parameters_markdown() -> str:
    lines = []
    for key, specs in parameter_groups():
        lines += [f"## {_GROUP_TITLES.get(key, f'`{key}.*`')}", ""]
        lines += ["| parameter | type | default | allowed | what |", "| --- | --- | --- | --- | --- |"]
        for spec in specs:
            kind = _TYPE_NAMES[spec.kind] + (", per joint" if spec.per_joint else "")
            if spec.choices is not None:
                allowed = ", ".join(f"`{_value(c)}`" for c in spec.choices)
            elif spec.low is not None:
                allowed = f"{spec.low:g} .. {spec.high:g}"
            else:
                allowed = ""
            lines.append(
                f"| `{spec.name}` | {kind} | `{_cell(_value(spec.default))}` | {allowed} | {_cell(spec.description)} |"
            )
        lines.append("")
    return "\n".join(lines)


def node_settings():
    """The settings of the two nodes the reference lists: one of joints (EXAMPLE_JOINTS) and one of one joint, each
    with every role's doors (the `doors` parameter closes the configuring ones by default) and a device
    (EXAMPLE_DEVICE) beside them."""
    from akd_ros import params

    every = {"doors": list(params.DOOR_ROLES)}
    device = {"devices": [EXAMPLE_DEVICE], f"devices.{EXAMPLE_DEVICE}.slave": len(EXAMPLE_JOINTS)}
    return params.settings({"joints": list(EXAMPLE_JOINTS), **device, **every}), params.settings({**device, **every})


def generic(name: str, joints: bool) -> str | None:
    """A declared name as the reference writes it (~/ for the node's own, ~/<joint>/ for a joint's); None for
    another joint than the one standing for all."""
    from akd_ros.node.node_state import NODE_NAME

    own = f"/{NODE_NAME}/"
    if not name.startswith(own):
        return name
    rest = name[len(own) :]
    if rest.startswith(f"{EXAMPLE_DEVICE}/"):
        return f"~/{DEVICE}/{rest.partition('/')[2]}"
    if joints:
        first, _, tail = rest.partition("/")
        if first == EXAMPLE_JOINTS[0] and tail:
            return f"~/{JOINT}/{tail}"
        if first in EXAMPLE_JOINTS[1:] and tail:
            return None
    return f"~/{rest}"


def doors() -> dict[str, dict[str, dict]]:
    """Every topic, service and action by kind ("topics", "services", "actions") and generic name: its type,
    direction, QoS and its name on a node of one joint (None where that node lacks it)."""
    from akd_ros.node.interface import ACTION, PUBLISHER, SERVICE, declared
    from akd_ros.zenoh.types import Types

    types = Types()
    of_joints, of_one = (declared(s, types) for s in node_settings())
    kinds = {SERVICE: "services", ACTION: "actions"}
    found: dict[str, dict[str, dict]] = {"topics": {}, "services": {}, "actions": {}}
    for endpoint in of_joints:
        name = generic(endpoint.name, joints=True)
        if name is None:
            continue
        kind = kinds.get(endpoint.kind, "topics")
        found[kind][name] = {
            "type": endpoint.type_name,
            "direction": "published" if endpoint.kind == PUBLISHER else "subscribed",
            "qos": endpoint.qos,
            "one_joint": None,
        }
    for endpoint in of_one:
        name = generic(endpoint.name, joints=False)
        kind = kinds.get(endpoint.kind, "topics")
        per_joint = name.replace("~/", f"~/{JOINT}/", 1)
        # A name both nodes have is the same door; else the joint's under ~/ (the one joint's topics, or its services).
        entry = found[kind].get(name) or found[kind].get(per_joint)
        if entry is None:
            raise ExtensionError(f"{name}, declared by a node of one joint, is not declared by a node of joints")
        if entry["one_joint"] is None:
            entry["one_joint"] = name
    return found


def _described(found: dict[str, dict[str, dict]]) -> dict[str, dict[str, str]]:
    descriptions = yaml.safe_load(DESCRIPTIONS.read_text(encoding="utf-8"))
    for kind, entries in found.items():
        given = descriptions.get(kind) or {}
        if missing := sorted(set(entries) - set(given)):
            raise ExtensionError(f"{DESCRIPTIONS.name}: the node declares {kind} without a description: {missing}")
        if stale := sorted(set(given) - set(entries)):
            raise ExtensionError(f"{DESCRIPTIONS.name}: {kind} described that the node does not declare: {stale}")
    return descriptions


def _type_link(type_name: str) -> str:
    """The package's own types link to their definition on the messages page."""
    if type_name.startswith("akd_ros/"):
        return f"{{ref}}`{type_name} <{_label(type_name)}>`"
    return f"`{type_name}`"


def _label(type_name: str) -> str:
    return type_name.replace("/", "-").replace("_", "-").lower()


def _qos(qos) -> str:
    return f"{'reliable' if qos.reliable else 'best effort'}, depth {qos.depth}" + (
        ", transient local" if qos.transient_local else ""
    )


def _one(name: str | None) -> str:
    return "—" if name is None else f"`{name}`"


def topics_markdown(found: dict, descriptions: dict) -> str:
    lines = [
        "| topic | on a node of one joint | type | direction, QoS | what |",
        "| --- | --- | --- | --- | --- |",
    ]
    for name, entry in found["topics"].items():
        lines.append(
            f"| `{name}` | {_one(entry['one_joint'])} | {_type_link(entry['type'])} | "
            f"{entry['direction']}, {_qos(entry['qos'])} | {_cell(descriptions['topics'][name])} |"
        )
    return "\n".join(lines) + "\n"


def served_markdown(found: dict, descriptions: dict, kind: str) -> str:
    """The table of the services or the actions (`kind`) the node serves."""
    lines = [f"| {kind[:-1]} | on a node of one joint | type | what |", "| --- | --- | --- | --- |"]
    for name, entry in found[kind].items():
        lines.append(
            f"| `{name}` | {_one(entry['one_joint'])} | {_type_link(entry['type'])} | "
            f"{_cell(descriptions[kind][name])} |"
        )
    return "\n".join(lines) + "\n"


def interface_files() -> list[Path]:
    """Every interface definition of the package: msg/*.msg, srv/*.srv, action/*.action."""
    return [
        path
        for directory in INTERFACE_DIRS
        if (ROOT / directory).is_dir()
        for path in sorted((ROOT / directory).iterdir())
        if path.suffix == f".{directory}"
    ]


def messages_markdown(found: dict) -> str:
    users: dict[str, list[str]] = {}
    for kind in ("topics", "services", "actions"):
        for name, entry in found[kind].items():
            users.setdefault(entry["type"], []).append(name)
    lines = []
    for path in interface_files():
        type_name = f"akd_ros/{path.parent.name}/{path.stem}"
        used = ", ".join(f"`{name}`" for name in users.get(type_name, [])) or "no topic, service or action of the node"
        lines += [f"({_label(type_name)})=", f"## `{type_name}`", "", f"Carried by {used}.", ""]
        lines += ["```text", path.read_text(encoding="utf-8").rstrip(), "```", ""]
    return "\n".join(lines)


def console_scripts() -> list[tuple[str, str]]:
    """The package's command-line tools: (name, entry point), in setup.py's order."""
    entry_points = importlib.metadata.distribution("akd_ros").entry_points
    return [(e.name, e.value) for e in entry_points if e.group == "console_scripts"]


def tools_markdown() -> str:
    lines = []
    env = dict(os.environ, COLUMNS="100")
    for name, _ in console_scripts():
        program = Path(sys.executable).parent / name
        shown = subprocess.run(
            [str(program), "--help"], capture_output=True, text=True, timeout=60, env=env, check=False
        )
        if shown.returncode != 0:
            raise ExtensionError(f"{name} --help exited {shown.returncode}: {shown.stderr.strip()}")
        lines += [f"## `{name}`", "", "```text", shown.stdout.rstrip(), "```", ""]
    return "\n".join(lines)


def write_all() -> dict[str, str]:
    """Every generated page by file name."""
    found = doors()
    descriptions = _described(found)
    return {
        "parameters.md": parameters_markdown(),
        "topics.md": topics_markdown(found, descriptions),
        "services.md": served_markdown(found, descriptions, "services"),
        "actions.md": served_markdown(found, descriptions, "actions"),
        "messages.md": messages_markdown(found),
        "tools.md": tools_markdown(),
    }


def _generate(app, config) -> None:
    GENERATED.mkdir(exist_ok=True)
    for name, text in write_all().items():
        path = GENERATED / name
        # Unchanged files keep their time, so an incremental build reads only the pages that changed.
        if not path.exists() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")


def setup(app):
    app.connect("config-inited", _generate)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
