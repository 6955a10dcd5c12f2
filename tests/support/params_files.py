"""Parameters files for akd_node's tests: a file from its ros__parameters lines, and the bad files with what their
refusal says, whether the node on rclpy reads them (tests/test_node_params.py) or `akd_ros.params` alone does
(tests/test_params_file.py)."""

from __future__ import annotations

from pathlib import Path


def params_file(directory: Path, body: str) -> Path:
    """A parameters file for akd_node whose ros__parameters are `body` (YAML lines)."""
    path = directory / "params.yaml"
    lines = "".join(f"    {line}\n" for line in body.strip().splitlines())
    path.write_text(f"akd_node:\n  ros__parameters:\n{lines}")
    return path


BAD_FILES = {
    "wrong type": ("cycle_time: fast", ["parameter cycle_time must be a number in [0.00025, 0.01]", "'fast'"]),
    "real for an integer": ("slave: 1.5", ["parameter slave must be an integer in [0, 65535]"]),
    "cycle below 250 us": ("cycle_time: 0.0001", ["parameter cycle_time", "[0.00025, 0.01]", "0.0001"]),
    "cycle above 10 ms": ("cycle_time: 0.02", ["parameter cycle_time", "[0.00025, 0.01]"]),
    "unknown mode": (
        "mode: cyclic_synchronous_velocity",
        [
            "parameter mode must be one of profile_position",
            "cyclic_synchronous_position",
            "'cyclic_synchronous_velocity'",
        ],
    ),
    "unknown fixed mapping": (
        "mapping: 0x1799/0x1B01",
        ["parameter mapping", "0x1799 is not a fixed RxPDO", "0x1701", "0x1725"],
    ),
    "unknown fixed tx mapping": ("mapping: 0x1724/0x1B99", ["parameter mapping", "0x1B99", "0x1B26"]),
    "mapping no mapping": ("mapping: csp", ["parameter mapping 'csp' is not a mapping", "'default'", "'flexible'"]),
    "flexible entry unmappable": (
        'mapping: flexible\nmapping.rx: ["0x6040:00/16 0x1234:56/32"]\nmapping.tx: ["0x6041:00/16 0x6064:00/32"]',
        ["parameter mapping", "0x1234:56"],
    ),
    "flexible entry malformed": (
        'mapping: flexible\nmapping.rx: ["6040-16"]\nmapping.tx: ["0x6041:00/16"]',
        ["parameter mapping.rx", "'6040-16'", "INDEX:SUB/BITS"],
    ),
    "flexible lists without flexible": ('mapping.rx: ["0x6040:00/16"]', ["mapping.rx", "'flexible' only"]),
    "mode the mapping cannot carry": (
        "mode: cyclic_synchronous_position\nmapping: 0x1701/0x1B01",
        ["parameters mode/mapping", "0x607A", "lacks"],
    ),
    "missing interface": (
        "link: akd_missing0",
        ["parameter link", "'akd_missing0' does not exist", "'sim'", "udp://HOST:PORT", "lo"],
    ),
    "udp without port": ("link: udp://127.0.0.1", ["parameter link", "udp://HOST:PORT", "1..65535"]),
    "more virtual AKDs than a bus holds": (
        "link: sim:100",
        ["parameter link", "sim:100", "the number of virtual AKDs must be 1..=64"],
    ),
    "unknown parameter": ("cycle_tme: 0.001", ["unknown parameter cycle_tme", "cycle_time"]),
    "direction": ("direction: 0", ["parameter direction must be one of 1, -1"]),
    "linear without lead": ("axis: linear", ["axis/lead", "lead", "linear"]),
    "lead on a rotary axis": ("lead: 0.005", ["parameter lead", "rotary", "0"]),
    "limits crossed": (
        "limits.min_position: 2.0\nlimits.max_position: 1.0",
        ["limits", "min_position", "max_position"],
    ),
    "limit policy": ("limits.policy: wrap", ["parameter limits.policy must be one of refuse, clamp"]),
    "latch": ('latch.arm: ["3/rising"]', ["parameter latch.arm", "'3/rising'", "1/rising", "2/falling"]),
    "fault reset policy": ("fault_reset: always", ["parameter fault_reset must be one of manual, auto_once"]),
    "command timeout policy": (
        "command_timeout_policy: coast",
        ["parameter command_timeout_policy must be one of hold, quick_stop"],
    ),
    "rate": ("joint_states_rate: 0.0", ["parameter joint_states_rate", "[1.0, 1000.0]"]),
    "bool": ("autostart: 1", ["parameter autostart must be a bool"]),
    "dc": ("dc: sometimes", ["parameter dc must be one of auto, on, off", "'sometimes'"]),
    "dc as a number": ("dc: 1", ["parameter dc must be one of auto, on, off", "got 1"]),
    "dc shift of a cycle": (
        "cycle_time: 0.001\ndc_shift: 0.001",
        ["parameter dc_shift must be less than one cycle_time (0.001 s) either way", "0.001"],
    ),
    "dc shift out of range": ("dc_shift: 0.5", ["parameter dc_shift must be a number in [-0.01, 0.01]", "0.5"]),
    "YAML syntax error": (
        "link: [sim\nmode: x",
        ["parameters file", "line 4, column 9", "expected ',' or ']'", "while parsing a flow sequence"],
    ),
    "fault reaction": ("fault_reaction: some", ["parameter fault_reaction must be one of all, joint", "'some'"]),
    "joint name not a name token": ("joints: [arm/1]", ["parameter joints: 'arm/1' is not a joint name", "joint_1"]),
    "joint named twice": ("link: sim:2\njoints: [a, a]", ["parameter joints names a more than once"]),
    "joint_name beside joints": (
        "link: sim:2\njoints: [a, b]\njoint_name: c",
        ["parameter joint_name applies to a file without joints", "joints.<name>.slave"],
    ),
    "a block of a joint not in joints": (
        "link: sim:2\njoints: [a, b]\njoints.c.mode: homing",
        ["unknown parameter joints.c.mode", "joints.<name>.<one of slave, alias, mode"],
    ),
    "a parameter no joint block has": (
        "link: sim:2\njoints: [a, b]\njoints.a.cycle_time: 0.002",
        ["unknown parameter joints.a.cycle_time"],
    ),
    "a bad value in a joint block": (
        "link: sim:2\njoints: [a, b]\njoints.b.mode: fast",
        ["parameter joints.b.mode must be one of profile_position", "'fast'"],
    ),
    "a bad mapping in a joint block": (
        "link: sim:2\njoints: [a, b]\njoints.b.mapping: 0x1799/0x1B01",
        ["parameter joints.b.mapping", "0x1799 is not a fixed RxPDO"],
    ),
    "a bad latch in a joint block": (
        'link: sim:2\njoints: [a, b]\njoints.a.latch.arm: ["1/up"]',
        ["parameter joints.a.latch.arm: '1/up' is not CHANNEL/EDGE"],
    ),
    "two joints on one drive": (
        "link: sim:2\njoints: [a, b]\njoints.b.slave: 0",
        ["parameters joints.<name>.slave/alias", "slave 0 given to several drives"],
    ),
    "a joint past the last drive": (
        "link: sim:2\njoints: [a, b, c]",
        [
            "the drives (a (slave 0), b (slave 1), c (slave 2))",
            "slave 2 is not on the bus: the line has 2 slaves (0..1); drive c expects an AKD there",
        ],
    ),
    "a device without its slave": ("devices: [valves]", ["parameter devices.valves.slave must be given", "akd-scan"]),
    "a device named as a joint": (
        "link: sim:2\njoints: [a, b]\ndevices: [a]\ndevices.a.slave: 1",
        ["parameter devices names a more than once (or as a joint)"],
    ),
    "two devices on one slave": (
        "link: sim:2\njoints: [a]\ndevices: [valves, lamps]\ndevices.valves.slave: 1\ndevices.lamps.slave: 1",
        ["parameters devices.<name>.slave: slave 1 given to several devices; each device once"],
    ),
    "a device on a joint's slave": (
        "link: sim:2\njoints: [a]\ndevices: [valves]\ndevices.valves.slave: 0",
        ["slave 0 is given to a drive and to device valves; each slave once"],
    ),
    "a device's product unknown to the line": (
        "link: sim:ek1100,el1004,el2004,akd?pace=immediate\nslave: 3\ndevices: [valves]\ndevices.valves.slave: 2\n"
        "devices.valves.product: EL9999",
        ["configure: ", "slave 2 is an EL2004; device valves expects an EL9999"],
    ),
    "a block of a device not in devices": (
        "devices: [valves]\ndevices.valves.slave: 1\ndevices.lamps.slave: 2",
        ["unknown parameter devices.lamps.slave", "devices.<name>.<one of slave, product>"],
    ),
    "an unknown product in the link": (
        "link: sim:ek1100,el9999,akd",
        ["parameter link", '"el9999", is no product the simulator makes: allowed are akd, ek1100'],
    ),
    "a device of another product than the line's": (
        "link: sim:ek1100,el1004,el2004,akd?pace=immediate\nslave: 3\ndevices: [valves]\ndevices.valves.slave: 2\n"
        "devices.valves.product: EL2008",
        ["configure: ", "slave 2 is an EL2004; device valves expects an EL2008"],
    ),
    "a device past the end of the line": (
        "link: sim:ek1100,el1004,akd?pace=immediate\nslave: 2\ndevices: [valves]\ndevices.valves.slave: 5",
        ["slave 5 is not on the bus: the line has 3 slaves (0..2); device valves expects a device there"],
    ),
    "a joint where the line has a terminal": (
        "link: sim:ek1100,el1004,akd?pace=immediate\nslave: 1",
        ["slave 1 is an EL1004; drive akd_axis expects an AKD"],
    ),
    # Port 9 (discard) on loopback: nothing listens, so the configure fails and the node ends.
    "a line with no drives listening": (
        "link: udp://127.0.0.1:9",
        ["configure: the drives (slave 0) on link 'udp://127.0.0.1:9' did not open", "no simulator listening"],
    ),
}
"""Each bad file's ros__parameters lines and the texts its refusal contains, by case."""
