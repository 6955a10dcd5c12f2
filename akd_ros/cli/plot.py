"""akd-plot BAG -o FILE.png: one picture of a recorded run, to see what happened around a fault.

BAG is a rosbag2 directory written by akd_ros (akd_ros.recorder); of a bag of several joints it draws one,
--joint NAME or the first. The picture has, against the
time since the first cycle sample: position and command, following error, torque and the DS402
state read from the statusword, each with the faults (red, with code, text and what the driver
did) and latch captures (green, with channel, edge and position) drawn across; where the bag has
the joint's I/O (~/io), its digital inputs, switches, hardware enable and outputs as steps, by the
names the node gave them; and a histogram of the cycle periods. Cycle samples come from
the cycle topic and the black box (the seconds before each fault, shaded) alike. A bag whose
recorder was killed is read after ``--reindex`` (akd_ros.recorder.reindex).
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

from akd_ros import _native
from akd_ros.cli.common import EXIT_FAILURE, run, tool_parser

CYCLE_SAMPLE = "akd_ros/msg/CycleSample"
LATCH_EVENT = "akd_ros/msg/LatchEvent"
DRIVE_FAULT = "akd_ros/msg/DriveFault"
DRIVE_IO = "akd_ros/msg/DriveIO"
# DriveIO's HARDWARE_ENABLE_LOW (msg/DriveIO.msg).
_HARDWARE_ENABLE_LOW = 2
#: File types the picture can be written as, by extension.
FORMATS = (".png", ".svg", ".pdf")
_EDGES = {1: "rising", 2: "falling"}
# DS402 states in the order of CiA 402's state diagram (the extension's), bottom to top of the state panel.
_DS402_STATES = _native.DS402_STATES
# Legend lines are wrapped to this many characters, so long fault actions stay inside the picture.
_LEGEND_WIDTH = 150


@dataclass
class Run:
    """What a bag holds for the picture: cycle samples by cycle number, latches and faults.

    ``samples`` maps cycle number to (time_ns, sample); ``black_box`` lists (first, last) time of
    each black box dump; ``latches`` and ``faults`` are (time_ns, message) in time order.
    """

    samples: dict = field(default_factory=dict)
    joint: str = ""
    """The joint drawn (a bag of a bus of joints has each cycle once per joint)."""
    joints: list = field(default_factory=list)
    """Every joint the bag's cycle samples name, in their order."""
    black_box: list = field(default_factory=list)
    latches: list = field(default_factory=list)
    faults: list = field(default_factory=list)
    io: list = field(default_factory=list)
    """(time_ns, DriveIO) of the joint, in time order."""
    topics: dict = field(default_factory=dict)


def read_run(bag: Path, joint: str | None = None) -> Run:
    """Reads a bag's cycle samples, latch events and faults of `joint` (None: the first joint in the bag).

    Raises FileNotFoundError for no bag, ValueError for one that rosbags cannot read or a joint it does not have."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if bag.is_file() and bag.suffix == ".mcap":
        bag = bag.parent
    if not (bag / "metadata.yaml").is_file():
        raise FileNotFoundError(f"no bag at {bag}: expected a rosbag2 directory with metadata.yaml")
    result = Run()
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            result.topics = {c.topic: c.msgtype for c in reader.connections}
            connections = reader.connections
            black_box_topics = {c.topic for c in connections if c.topic.endswith("/black_box")}
            kinds = (CYCLE_SAMPLE, LATCH_EVENT, DRIVE_FAULT, DRIVE_IO)
            wanted = [c for c in connections if c.msgtype in kinds]
            dump: list = []
            samples: dict = {}
            latches: list = []
            faults: list = []
            io: list = []
            for connection, time_ns, raw in reader.messages(connections=wanted):
                msg = reader.deserialize(raw, connection.msgtype)
                # Bags of a single axis recorded before CycleSample named its joint have none.
                name = getattr(msg, "joint", "")
                if connection.msgtype == CYCLE_SAMPLE:
                    if name not in samples:
                        samples[name] = {}
                    samples[name][msg.cycle] = (time_ns, msg)
                    if connection.topic in black_box_topics:
                        dump.append((name, time_ns))
                elif connection.msgtype == LATCH_EVENT:
                    latches.append((time_ns, msg))
                elif connection.msgtype == DRIVE_IO:
                    io.append((time_ns, msg))
                else:
                    faults.append((time_ns, msg))
    except Exception as err:
        raise ValueError(
            f"cannot read bag {bag}: {err} (if its recorder was killed, run akd-plot with --reindex)"
        ) from err
    result.joints = list(samples)
    if joint is not None and joint not in samples:
        raise ValueError(
            f"bag {bag} has no cycle samples of joint {joint!r} (its joints: {', '.join(samples) or 'none'})"
        )
    result.joint = joint if joint is not None else next(iter(samples), "")
    result.samples = samples.get(result.joint, {})
    result.latches = [(t, m) for t, m in latches if len(samples) < 2 or m.joint == result.joint]
    result.faults = [(t, m) for t, m in faults if len(samples) < 2 or m.joint == result.joint]
    result.io = sorted(((t, m) for t, m in io if len(samples) < 2 or m.joint == result.joint), key=lambda x: x[0])
    result.black_box = _spans(sorted(t for name, t in dump if name == result.joint))
    return result


def _spans(times: list, gap_ns: int = 100_000_000) -> list:
    """Groups sorted times into (first, last) spans, a new span after a gap longer than gap_ns."""
    spans: list = []
    for t in times:
        if spans and t - spans[-1][1] <= gap_ns:
            spans[-1][1] = t
        else:
            spans.append([t, t])
    return [tuple(s) for s in spans]


def fault_label(msg) -> str:
    """One line for a fault: code, text, source and what the driver did."""
    code = f"0x{msg.code:04X} " if msg.code else ""
    al = f", AL 0x{msg.al_status_code:04X}" if msg.al_status_code else ""
    return f"FAULT {code}{msg.text or msg.source} [{msg.source}{al}] -> {msg.action}"


def latch_label(msg) -> str:
    """One line for a latch capture: channel, edge and position."""
    return f"latch {msg.channel} {_EDGES.get(msg.edge, f'edge {msg.edge}')} @ {msg.position:.4g}"


def ds402_state(statusword: int) -> int:
    """The index in _DS402_STATES of the state a statusword shows, -1 for none."""
    state = _native.Ds402State.from_statusword(statusword)
    return -1 if state is None else _DS402_STATES.index(state)


def io_steps(io: list) -> list[tuple[str, list[bool]]]:
    """The I/O signals of (time, DriveIO) pairs worth a step trace, each (label, its level in each message): every
    named input and output by its name, every other input and output and every switch that was ever high, and the
    hardware enable where it was ever low."""
    messages = [m for _, m in io]
    if not messages:
        return []
    last = messages[-1]
    signals: list[tuple[str, list[bool]]] = []

    def add(label: str, levels: list[bool], named: bool = False) -> None:
        if named or any(levels):
            signals.append((label, levels))

    def level(m, field: str, index: int) -> bool:
        values = getattr(m, field)
        return bool(values[index]) if index < len(values) else False

    names = {int(n) - 1: name for name, n in zip(last.input_names, last.input_numbers, strict=True)}
    for i in range(len(last.inputs)):
        add(names.get(i, f"DI{i + 1}"), [level(m, "inputs", i) for m in messages], i in names)
    for switch in ("negative_limit", "positive_limit", "home_switch", "interlock"):
        add(switch.replace("_", " "), [bool(getattr(m, switch)) for m in messages])
    add("hardware enable low", [m.hardware_enable == _HARDWARE_ENABLE_LOW for m in messages])
    names = {int(n) - 1: name for name, n in zip(last.output_names, last.output_numbers, strict=True)}
    for o in range(len(last.outputs)):
        add(names.get(o, f"DO{o + 1}"), [level(m, "outputs", o) for m in messages], o in names)
    return signals


def plot(run_data: Run, title: str, output: Path) -> None:
    """Draws the run into output (its extension picks the format)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    cycles = sorted(run_data.samples)
    times = np.array([run_data.samples[c][0] for c in cycles], dtype=np.int64)
    samples = [run_data.samples[c][1] for c in cycles]
    t0 = times[0]

    def seconds(time_ns) -> float:
        return (time_ns - t0) / 1e9

    t = seconds(times)
    column = {
        name: np.array([getattr(s, name) for s in samples], dtype=float)
        for name in ("position", "command", "following_error", "torque", "period_ns")
    }

    states = np.array([ds402_state(s.statusword) for s in samples])

    signals = io_steps(run_data.io)
    panels = 6 if signals else 5
    figure = plt.figure(figsize=(13, 11 + 2 * (panels - 5)), layout="constrained")
    grid = figure.add_gridspec(panels, 1, height_ratios=[3, 2, 2, 2, *([2] if signals else []), 2])
    ax_position = figure.add_subplot(grid[0])
    ax_error = figure.add_subplot(grid[1], sharex=ax_position)
    ax_torque = figure.add_subplot(grid[2], sharex=ax_position)
    ax_state = figure.add_subplot(grid[3], sharex=ax_position)
    ax_io = figure.add_subplot(grid[4], sharex=ax_position) if signals else None
    ax_period = figure.add_subplot(grid[-1])
    ax_position.set_title(title, fontsize=11)

    ax_position.plot(t, column["position"], lw=1.2, label="position")
    ax_position.plot(t, column["command"], lw=1.0, ls="--", label="command")
    ax_position.set_ylabel("position (rad or m)")
    ax_error.plot(t, column["following_error"], lw=1.0, color="tab:purple")
    ax_error.set_ylabel("following error\n(rad or m)")
    ax_torque.plot(t, column["torque"], lw=1.0, color="tab:brown")
    ax_torque.set_ylabel("torque (N·m or N)")
    ax_state.step(t, states, where="post", lw=1.5, color="tab:gray")
    ax_state.set_yticks(range(-1, len(_DS402_STATES)), ["no valid state", *map(str, _DS402_STATES)], fontsize=8)
    ax_state.set_ylim(-1.5, len(_DS402_STATES) - 0.5)
    ax_state.set_ylabel("DS402 state\n(statusword)")
    time_axes = (ax_position, ax_error, ax_torque, ax_state)
    if ax_io is not None:
        io_t = seconds(np.array([t for t, _ in run_data.io], dtype=np.int64))
        # Each signal a step between its row and 0.7 above it, in the order io_steps gives, first on top.
        for row, (_, levels) in enumerate(reversed(signals)):
            ax_io.step(io_t, row + 0.7 * np.array(levels, dtype=float), where="post", lw=1.3)
        ax_io.set_yticks(range(len(signals)), [label for label, _ in reversed(signals)], fontsize=8)
        ax_io.set_ylim(-0.5, len(signals))
        ax_io.set_ylabel("I/O (~/io)")
        time_axes = (*time_axes, ax_io)
    time_axes[-1].set_xlabel(f"time since the first cycle sample (s); cycles {cycles[0]}..{cycles[-1]}")

    for first, last in run_data.black_box:
        for ax in time_axes:
            ax.axvspan(
                seconds(first),
                seconds(last),
                color="0.85",
                zorder=0,
                label="black box (cycles before a fault)" if ax is ax_position else None,
            )
    for number, (time_ns, msg) in enumerate(run_data.latches, 1):
        _mark(time_axes, seconds(time_ns), f"L{number}", latch_label(msg), "tab:green", "--", number)
    for number, (time_ns, msg) in enumerate(run_data.faults, 1):
        _mark(time_axes, seconds(time_ns), f"F{number}", fault_label(msg), "tab:red", "-", number)
    for ax in time_axes:
        ax.grid(True, alpha=0.3)
    # The events' full text in one legend above the panels, where it hides no curve.
    handles, labels = ax_position.get_legend_handles_labels()
    labels = [textwrap.fill(label, _LEGEND_WIDTH, subsequent_indent="    ") for label in labels]
    figure.legend(handles, labels, loc="outside upper left", fontsize=9, ncols=1)

    period_us = column["period_ns"][column["period_ns"] > 0] / 1e3
    if period_us.size:
        # Log counts: the rare late cycles that matter would not show on a linear scale.
        bins = min(100, max(10, period_us.size // 20))
        ax_period.hist(period_us, bins=bins, color="tab:blue", log=True)
        ax_period.set_ylim(bottom=0.5)
        p50, p99 = np.percentile(period_us, [50, 99])
        ax_period.axvline(p50, color="k", lw=1)
        ax_period.set_title(
            f"cycle period: min {period_us.min():.1f}, median {p50:.1f}, 99 % {p99:.1f}, "
            f"max {period_us.max():.1f} µs ({period_us.size} samples)",
            fontsize=10,
        )
    else:
        ax_period.text(0.5, 0.5, "no cycle periods recorded", ha="center", transform=ax_period.transAxes)
    ax_period.set_xlabel("cycle period (µs)")
    ax_period.set_ylabel("cycles")
    figure.savefig(output, dpi=100)
    plt.close(figure)


def _mark(axes, x: float, tag: str, label: str, color: str, style: str, number: int) -> None:
    for ax in axes:
        legend = f"{tag} at {x:.3f} s: {label}" if ax is axes[0] else None
        ax.axvline(x, color=color, ls=style, lw=1.5, label=legend)
    # Tags step down, so events close in time (an emergency and the Fault state) stay readable.
    axes[0].annotate(
        tag,
        xy=(x, 1.0),
        xycoords=("data", "axes fraction"),
        xytext=(3, -12 * (1 + (number - 1) % 4)),
        textcoords="offset points",
        fontsize=9,
        color=color,
        fontweight="bold",
    )


def _output(text: str) -> Path:
    path = Path(text)
    if path.suffix.lower() not in FORMATS:
        raise argparse.ArgumentTypeError(f"{text}: the picture's file name must end in one of {', '.join(FORMATS)}")
    return path


EXAMPLES = """examples:
  akd-plot bags/run_2026-01-01 -o run.png
  akd-plot bags/arm --joint joint_2 -o joint_2.svg
  akd-plot bags/killed --reindex -o killed.png   a bag whose recorder was killed
"""


def main(argv: list[str] | None = None) -> int:
    """akd-plot's entry point; returns the exit status: 0, or 1 for a bag it cannot plot.

    argparse exits with 2 for bad arguments (e.g. an output type not in FORMATS)."""
    parser = tool_parser("akd-plot", __doc__.splitlines()[0], EXAMPLES)
    parser.add_argument("bag", metavar="BAG", type=Path, help="rosbag2 directory recorded by akd_ros")
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        type=_output,
        metavar="FILE.png",
        help=f"picture to write ({', '.join(FORMATS)})",
    )
    parser.add_argument(
        "--joint", metavar="NAME", help="the joint to draw, of a bag of several (default: the first in the bag)"
    )
    parser.add_argument(
        "--reindex",
        action="store_true",
        help="first rebuild the bag's summaries and metadata.yaml (after a killed recording)",
    )
    args = parser.parse_args(argv)

    def body() -> int:
        if args.reindex:
            from akd_ros.recorder import reindex

            reindex(args.bag)
        run_data = read_run(args.bag, args.joint)
        if not run_data.samples:
            topics = ", ".join(f"{name} ({kind})" for name, kind in sorted(run_data.topics.items())) or "none"
            print(
                f"akd-plot: error: bag {args.bag} has no {CYCLE_SAMPLE} messages (its topics: {topics})",
                file=sys.stderr,
            )
            return EXIT_FAILURE
        of_joint = f" of {run_data.joint}" if run_data.joint else ""
        title = (
            f"{args.bag.name}: {len(run_data.samples)} cycle samples{of_joint}, "
            f"{len(run_data.faults)} fault(s), {len(run_data.latches)} latch capture(s)"
        )
        plot(run_data, title, args.output)
        print(args.output)
        return 0

    # Reading a bag needs no capability at all: root is not warned of CAP_NET_RAW here.
    return run("akd-plot", body, opens_a_link=False)


if __name__ == "__main__":
    sys.exit(main())
