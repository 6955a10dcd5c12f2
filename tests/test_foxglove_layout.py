"""The Foxglove layouts the repository ships (config/foxglove.json, config/foxglove_6axis.json) against what the node
records: Foxglove itself cannot run here, so every topic and message path a panel names is looked up in a bag the
node recorded with the layout's own parameters file, read with mcap's reader and decoded by rosbags from the schemas
the bag carries; the diagnostics panel's status is one the bag's /diagnostics has, and the state indicator's rules
name the states the bag's statuses spell. The shipped files are what `akd_ros.node.foxglove_layout` makes of their
parameters files, and a layout of a node's other joints is made from its own file.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from akd_ros.node.foxglove_layout import layout
from akd_ros.params import read_parameters_file, settings
from support.ros import WAIT_S, NodeProcess, ros_environment, stop
from support.waiting import wait_for

REPO = Path(__file__).resolve().parents[1]
DOMAINS = range(80, 84)
LAYOUTS = {"foxglove.json": "akd_sim.yaml", "foxglove_6axis.json": "akd_sim_6axis.yaml"}
"""Each shipped layout and the parameters file it is made of."""
PATH = re.compile(r'^(?P<topic>/[^.{]+)(?:\{(?P<field>\w+)=="(?P<value>[^"]*)"\})?(?:\.(?P<members>.+))?$')
"""A message path as the layouts write them: /topic, then a filter {field=="value"}, then .member[index]...."""
KEPT = 12
"""Messages decoded per topic: enough for every joint's CycleSample of one cycle."""


def made(parameters: str) -> dict:
    return layout(settings(read_parameters_file(str(REPO / "config" / parameters))))


@pytest.mark.parametrize("shipped", sorted(LAYOUTS))
def test_the_shipped_layouts_are_what_the_module_makes_of_their_parameters_files(shipped):
    assert json.loads((REPO / "config" / shipped).read_text()) == made(LAYOUTS[shipped])


def test_a_layout_is_printed_for_the_parameters_on_the_command_line_and_a_bad_one_is_one_line(tmp_path):
    path = tmp_path / "arm.yaml"
    path.write_text(yaml.safe_dump({"akd_node": {"ros__parameters": {"link": "sim:2", "joints": ["hip", "knee"]}}}))
    command = [sys.executable, "-m", "akd_ros.node.foxglove_layout", "--node", "/cell/akd_node"]
    done = subprocess.run([*command, "--ros-args", "--params-file", str(path)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    printed = json.loads(done.stdout)
    tabs = [t["title"] for t in printed["configById"][printed["layout"]]["tabs"]]
    assert tabs == ["joints", "hip", "knee", "line"]
    assert printed["configById"]["Plot!knee_following_error"]["paths"][0]["value"] == (
        "/cell/akd_node/knee/status.following_error"
    )
    bad = subprocess.run([*command, "--ros-args", "-p", "cycle_time:=7.0"], capture_output=True, text=True)
    assert bad.returncode == 1 and bad.stdout == ""
    assert bad.stderr.count("\n") == 1 and "parameter cycle_time must be" in bad.stderr, bad.stderr


def panels_of(tree, found: list[str]) -> list[str]:
    """The panel ids a layout tree holds, tabs' trees included."""
    if isinstance(tree, str):
        found.append(tree)
    elif tree is not None:
        panels_of(tree["first"], found)
        panels_of(tree["second"], found)
    return found


def paths_of(document: dict) -> tuple[set[str], list[tuple[str, str]]]:
    """(topics, message paths with their panel) the layout's panels name."""
    topics, paths = set(), []
    for panel, config in document["configById"].items():
        kind = panel.split("!")[0]
        if kind in ("Plot", "StateTransitions"):
            paths += [(panel, series["value"]) for series in config["paths"]]
        elif kind == "Indicator":
            paths.append((panel, config["path"]))
        elif kind == "RawMessages":
            topics.add(config["topicPath"])
        elif kind in ("DiagnosticSummary", "DiagnosticStatusPanel"):
            topics.add(config["topicToRender"])
    return topics, paths


def record(parameters: str, folder: Path, domain: int) -> Path:
    """The MCAP file of a bag the node records with config/`parameters`, every joint enabled and holding, a few
    /diagnostics long."""
    values = yaml.safe_load((REPO / "config" / parameters).read_text())
    values["akd_node"]["ros__parameters"] |= {
        "record.enabled": True,
        "record.folder": str(folder / "bags"),
        "record.decimation": 10,
        "enable_on_start": True,
    }
    path = folder / parameters
    path.write_text(yaml.safe_dump(values))
    node = NodeProcess(path, domain)
    try:
        wait_for(
            "the joints enabled and the bag opened",
            lambda: (
                node.process.poll() is not None
                or ("enable_on_start: " in node.output() and len(list((folder / "bags").glob("*/*.mcap"))) == 1)
            ),
            WAIT_S,
            0.05,
        )
        assert node.process.poll() is None, node.output()
        # Three seconds more: /diagnostics at 1 Hz published a few times, with every joint enabled.
        time.sleep(3.0)
        node.process.send_signal(signal.SIGINT)
        assert node.process.wait(timeout=WAIT_S) == 0, node.output()
    finally:
        stop(node.process)
        print(f"akd_node output:\n{node.output()}")
    (bag,) = (folder / "bags").glob("*/*.mcap")
    return bag


def decoded(bag: Path) -> tuple[set[str], dict[str, list]]:
    """The bag's topics, and the first KEPT messages of each, decoded by rosbags from the bag's schemas."""
    store = get_typestore(Stores.EMPTY)
    messages: dict[str, list] = {}
    with bag.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        topics = {c.topic for c in summary.channels.values()}
        for schema in summary.schemas.values():
            store.register(get_types_from_msg(schema.data.decode(), schema.name))
        for schema, channel, message in reader.iter_messages():
            kept = messages.setdefault(channel.topic, [])
            if len(kept) < KEPT:
                kept.append(store.deserialize_cdr(message.data, schema.name))
    return topics, messages


def resolve(message, members: str):
    """`members` (a.b[2].c) of `message`; AttributeError or IndexError where it does not exist."""
    value = message
    for name, index in re.findall(r"(\w+)(?:\[(\d+)\])?", members):
        value = getattr(value, name)
        if index:
            value = value[int(index)]
    return value


@pytest.mark.parametrize("shipped", sorted(LAYOUTS))
def test_every_topic_and_path_of_the_shipped_layout_is_in_a_bag_the_node_recorded(shipped, tmp_path):
    document = json.loads((REPO / "config" / shipped).read_text())
    with ros_environment(DOMAINS) as domain:
        bag = record(LAYOUTS[shipped], tmp_path, domain)
    topics, messages = decoded(bag)
    named_topics, paths = paths_of(document)
    assert named_topics <= topics, named_topics - topics
    for panel, path in paths:
        parts = PATH.match(path)
        assert parts and parts["members"], f"{panel}: {path} is not a path to a field"
        assert parts["topic"] in topics, f"{panel}: {parts['topic']} is not in the bag"
        candidates = messages.get(parts["topic"], [])
        if parts["field"]:
            candidates = [m for m in candidates if str(getattr(m, parts["field"])) == parts["value"]]
        assert candidates, f"{panel}: no message of {path} in the bag"
        value = resolve(candidates[-1], parts["members"])
        assert isinstance(value, (int, float, str)), f"{panel}: {path} is {value!r}, not a value to show"
    # The line tab's detail panel shows a status the node publishes.
    detail = next(c for p, c in document["configById"].items() if p.startswith("DiagnosticStatusPanel!"))
    statuses = {(s.hardware_id, s.name) for array in messages["/diagnostics"] for s in array.status}
    assert (detail["selectedHardwareId"], detail["selectedName"]) in statuses, statuses
    # The indicators' rules spell the states as the statuses do: every joint enabled is green.
    indicator = next(c for p, c in document["configById"].items() if p.startswith("Indicator!"))
    rules = {rule["rawValue"]: rule["color"] for rule in indicator["rules"]}
    seen = {m.ds402_state for topic, kept in messages.items() if topic.endswith("/status") for m in kept}
    assert seen <= set(rules), seen - set(rules)
    assert "operation_enabled" in seen and rules["operation_enabled"] == "#2ca02c"


@pytest.mark.parametrize("shipped", sorted(LAYOUTS))
def test_the_layout_tree_holds_every_panel_once_under_its_tabs(shipped):
    document = json.loads((REPO / "config" / shipped).read_text())
    root = document["layout"]
    assert root.startswith("Tab!")
    held = [root]
    for tab in document["configById"][root]["tabs"]:
        panels_of(tab["layout"], held)
    assert sorted(held) == sorted(document["configById"]), set(held) ^ set(document["configById"])
