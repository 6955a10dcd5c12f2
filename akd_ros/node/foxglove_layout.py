"""A Foxglove layout of a node's joints and line, for its live view (`live_view.port`) and its bags alike.

The layout is Foxglove's layout file as its "Export..." writes it and its "Import from file..." reads it: each
panel's configuration by panel id (`configById`, the id's part before "!" the panel's type), how they are arranged
(`layout`, a tree of splits whose leaves are panel ids), `globalVariables`, `userNodes` and `playbackConfig`. Its
topics are the node's own, from its parameters; every series is ordered by the time a message arrived, which in a bag
is the message's stamp. The root is a Tab panel:

- joints: every joint's DS402 state as an indicator (green in Operation enabled, red in a fault, amber in Quick stop
  active) and over time, and every joint's position, velocity and torque (/joint_states' effort) in three plots;
- one tab per joint: its position, velocity, torque and following error (~/<joint>/status, at status_rate; in a bag
  also every recorded cycle's, from ~/cycle, the following error of each cycle), its DS402 state and mode over time,
  its last fault and its I/O;
- line: /diagnostics, every status in it (a joint's, the bus's, and whatever else the node adds there) and the bus's
  in detail, and the cycle's counters (lost frames, WKC errors, overruns) over time.

config/foxglove.json (a node of one joint, config/akd_sim.yaml) and config/foxglove_6axis.json (joint_1 to joint_6,
config/akd_sim_6axis.yaml) are made by this module; for a node of other joints:

    python -m akd_ros.node.foxglove_layout --ros-args --params-file my_robot.yaml > my_robot_layout.json
"""

from __future__ import annotations

import argparse
import json
import sys

from akd_ros import _native
from akd_ros.node.node_state import FAULT_STATES, NODE_NAME, namespace
from akd_ros.params import ParameterError, Settings, read_arguments, settings

GREEN, RED, AMBER, GREY = "#2ca02c", "#d62728", "#ff7f0e", "#7f7f7f"
STATE_COLOURS = {
    _native.Ds402State.OPERATION_ENABLED: GREEN,
    _native.Ds402State.QUICK_STOP_ACTIVE: AMBER,
} | dict.fromkeys(FAULT_STATES, RED)
"""The indicator's colour of a DS402 state (grey for the others)."""
COUNTERS = ("lost_frames", "wkc_errors", "overruns")
"""The cycle's counters of DriveStatus the line tab plots."""
TIME = "receiveTime"
"""How every series is ordered: by arrival live, by the recorded stamp in a bag."""


def _split(direction: str, *items):
    """A tree of splits in `direction` ("row": side by side, "column": one above the other) sharing the space evenly."""
    if len(items) == 1:
        return items[0]
    return {
        "first": items[0],
        "second": _split(direction, *items[1:]),
        "direction": direction,
        "splitPercentage": 100 / len(items),
    }


def _series(value: str, label: str) -> dict:
    return {"value": value, "label": label, "enabled": True, "timestampMethod": TIME}


class _Panels:
    """The panels' configurations by id, as they are added."""

    def __init__(self) -> None:
        self.by_id: dict[str, dict] = {}

    def add(self, kind: str, name: str, title: str, **config) -> str:
        panel = f"{kind}!{name}"
        self.by_id[panel] = {**config, "foxglovePanelTitle": title}
        return panel

    def plot(self, name: str, title: str, series: list[dict]) -> str:
        return self.add(
            "Plot",
            name,
            title,
            paths=series,
            showLegend=True,
            legendDisplay="floating",
            showPlotValuesInLegend=True,
            showXAxisLabels=True,
            showYAxisLabels=True,
            isSynced=True,
            xAxisVal="timestamp",
            sidebarDimension=240,
        )

    def states(self, name: str, title: str, series: list[dict]) -> str:
        return self.add("StateTransitions", name, title, paths=series, isSynced=True, showPoints=True)

    def indicator(self, name: str, title: str, path: str) -> str:
        rules = [
            {
                "operator": "=",
                "rawValue": state.snake_name,
                "color": STATE_COLOURS.get(state, GREY),
                "label": f"{state}",
            }
            for state in _native.DS402_STATES
        ]
        return self.add(
            "Indicator",
            name,
            title,
            path=path,
            style="background",
            rules=rules,
            fallbackColor=GREY,
            fallbackLabel="no valid DS402 state",
        )

    def raw(self, name: str, title: str, topic: str) -> str:
        return self.add(
            "RawMessages",
            name,
            title,
            topicPath=topic,
            diffEnabled=False,
            diffMethod="custom",
            diffTopicPath="",
            showFullMessageForDiff=False,
            expansion="all",
        )


def layout(settings: Settings, node: str = f"/{NODE_NAME}") -> dict:
    """The layout of the node `node` (its full name) run with `settings`, as a Foxglove layout file holds it."""
    panels = _Panels()
    joints = [j.name for j in settings.joints]
    ns = {j: f"{node}/{namespace(settings, j)[2:]}" for j in joints}
    status = {j: f"{ns[j]}status" for j in joints}
    quantities = (
        ("position", "position, rad (m)"),
        ("velocity", "velocity, rad/s (m/s)"),
        ("effort", "torque, N·m (N)"),
    )

    overview = _split(
        "column",
        _split("row", *(panels.indicator(f"{j}_state", j, f"{status[j]}.ds402_state") for j in joints)),
        panels.states("states", "DS402 state", [_series(f"{status[j]}.ds402_state", j) for j in joints]),
        *(
            panels.plot(field, title, [_series(f"/joint_states.{field}[{k}]", j) for k, j in enumerate(joints)])
            for field, title in quantities
        ),
    )
    tabs = [{"title": "joints", "layout": overview}]
    for k, j in enumerate(joints):
        # ~/cycle carries one CycleSample per joint and cycle: a node of joints tells them apart by `joint`.
        cycle = f"{node}/cycle" + (f'{{joint=="{j}"}}' if settings.joint_namespaces else "")
        plots = [
            panels.plot(f"{j}_{field}", f"{j} {title}", [_series(f"/joint_states.{field}[{k}]", j)])
            for field, title in quantities
        ]
        plots.append(
            panels.plot(
                f"{j}_following_error",
                f"{j} following error, rad (m)",
                [
                    _series(f"{status[j]}.following_error", "~/status"),
                    _series(f"{cycle}.following_error", "every cycle (a bag's ~/cycle)"),
                ],
            )
        )
        tabs.append(
            {
                "title": j,
                "layout": _split(
                    "row",
                    _split("column", _split("row", *plots[:2]), _split("row", *plots[2:])),
                    _split(
                        "column",
                        panels.indicator(f"{j}_state_of_tab", j, f"{status[j]}.ds402_state"),
                        panels.states(
                            f"{j}_states",
                            f"{j} state and mode",
                            [_series(f"{status[j]}.ds402_state", "DS402 state"), _series(f"{status[j]}.mode", "mode")],
                        ),
                        panels.raw(f"{j}_fault", f"{j} last fault", f"{ns[j]}fault"),
                        panels.raw(f"{j}_io", f"{j} I/O", f"{ns[j]}io"),
                    ),
                ),
            }
        )
    first = status[joints[0]]
    line = _split(
        "row",
        panels.add(
            "DiagnosticSummary",
            "line",
            "/diagnostics",
            topicToRender="/diagnostics",
            minLevel=0,
            pinnedIds=[],
            hardwareIdFilter="",
            sortByLevel=True,
        ),
        _split(
            "column",
            panels.add(
                "DiagnosticStatusPanel",
                "bus",
                "the bus",
                topicToRender="/diagnostics",
                selectedHardwareId=f"EtherCAT line {settings.link}",
                selectedName=f"{NODE_NAME}: bus",
            ),
            panels.plot("counters", "the cycle's counters", [_series(f"{first}.{c}", c) for c in COUNTERS]),
        ),
    )
    tabs.append({"title": "line", "layout": line})
    root = panels.add("Tab", "akd", "akd_node", activeTabIdx=0, tabs=tabs)
    return {
        "configById": panels.by_id,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1},
        "layout": root,
    }


def main(arguments: list[str] | None = None) -> int:
    """Prints the layout of the node the parameters on the command line (after --ros-args, as akd_node takes them)
    describe; exits 1 with one line for a bad parameter."""
    arguments = sys.argv if arguments is None else arguments
    own = arguments[1:]
    own = own[: own.index("--ros-args")] if "--ros-args" in own else own
    parser = argparse.ArgumentParser(
        prog="python -m akd_ros.node.foxglove_layout",
        usage="%(prog)s [--node NAME] --ros-args --params-file FILE [-p NAME:=VALUE ...]",
        description="Prints a Foxglove layout (JSON, for Import from file...) of the node these parameters describe.",
    )
    parser.add_argument("--node", default=f"/{NODE_NAME}", help="the node's full name (default /akd_node)")
    options = parser.parse_args(own)
    try:
        node_settings = settings(read_arguments(arguments, NODE_NAME))
    except ParameterError as e:
        print(f"{parser.prog}: error: {e}", file=sys.stderr)
        return 1
    print(json.dumps(layout(node_settings, options.node.rstrip("/")), indent=2, ensure_ascii=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
