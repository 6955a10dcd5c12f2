"""The schema of akd_node's parameters: `Spec` and `SCHEMA`, each parameter's type, default, range, allowed values
and description (the documentation's reference of parameters is generated from it); the names a parameters file may
give (a joint's block, its inputs' and outputs' names); and the checks of single values (the link, a PDO mapping,
limits, latches, addresses), each raising `ParameterError` naming the parameter and what is allowed."""

from __future__ import annotations

import ipaddress
import math
import re
import socket
from collections.abc import Mapping
from dataclasses import dataclass, replace

from akd_ros import _native
from akd_ros.axis import ANALOG_VOLTS_PER_COUNT, MODES
from akd_ros.bus import FAULT_REACTIONS
from akd_ros.units import Limits

TRANSPORTS = ("rclpy", "zenoh", "both")
"""Values of transport."""

CYCLE_TIME_RANGE = (0.00025, 0.01)
"""Cycle times the AKD takes, in seconds: 250 µs (4 kHz) to 10 ms."""
EDGES = ("rising", "falling")
"""Latch edges by name."""
FAULT_RESET_POLICIES = ("manual", "auto_once")
"""Values of fault_reset."""
COMMAND_TIMEOUT_POLICIES = ("hold", "quick_stop")
"""Values of command_timeout_policy."""
DC_CHOICES = {"auto": None, "on": True, "off": False}
DOOR_ROLES = ("observe", "operate", "configure")
"""The roles of the node's doors (akd_ros.node.doors), which the doors parameter opens."""
"""Values of dc, each with the Axis's `dc` (None: the link's default)."""
_TYPE_WORDS = {
    bool: "a bool (true or false)",
    int: "an integer",
    float: "a number",
    str: "a string",
    list: "a list of strings",
}
"""The words for each kind of value (`Spec.kind`)."""


class ParameterError(ValueError):
    """A parameter with a value the node cannot run with; the message names the parameter and what is allowed."""


@dataclass(frozen=True)
class Spec:
    """One parameter: its name, default (which gives its type), description and what values it allows."""

    name: str
    default: object
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple | None = None
    per_joint: bool = False
    """Whether each joint of `joints` has it in its block, as joints.<name>.<parameter>."""
    why_not: Mapping[str, str] | None = None
    """For values outside `choices` that a user may expect, why they are not among them."""

    def of_joint(self, joint: str, default: object) -> Spec:
        """This parameter in the block of `joint`, with `default` (the top-level value)."""
        return replace(
            self, name=f"joints.{joint}.{self.name}", default=default, description=f"Joint {joint}: {self.description}"
        )

    @property
    def kind(self) -> type:
        """The Python type of its values, from the default: bool, int, float, str or list (of strings)."""
        return type(self.default)

    def allowed(self) -> str:
        """What the parameter allows, in words."""
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        if self.low is not None:
            return f"{_TYPE_WORDS[self.kind]} in [{self.low}, {self.high}]"
        return _TYPE_WORDS[self.kind]

    def check(self, value: object) -> object:
        """`value` as this parameter's type (a whole number taken for a real one), or ParameterError."""
        kind = self.kind
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if kind is list and value is None:
            value = []  # an empty YAML list arrives without a type
        if kind is str and isinstance(value, bool) and {"on", "off"} <= set(self.choices or ()):
            # YAML 1.1, as rcl reads a file or -p, takes unquoted on/off (yes/no, true/false) for a bool.
            value = "on" if value else "off"
        if kind is list:
            typed = isinstance(value, list) and all(isinstance(v, str) for v in value)
        else:
            # The first that matches, as rclpy types a value: a bool is an int to isinstance.
            typed = next((t for t in (bool, int, float, str) if isinstance(value, t)), None) is kind
        if not typed:
            raise ParameterError(f"parameter {self.name} must be {self.allowed()}, got {value!r}")
        if self.choices is not None and value not in self.choices:
            why = (self.why_not or {}).get(value)
            raise ParameterError(
                f"parameter {self.name} must be {self.allowed()}, got {value!r}" + (f": {why}" if why else "")
            )
        if self.low is not None and not (self.low <= value <= self.high):
            raise ParameterError(f"parameter {self.name} must be {self.allowed()}, got {value!r}")
        return value


_INF = math.inf
SCHEMA: tuple[Spec, ...] = (
    Spec(
        "link",
        "sim",
        "The bus: 'sim' (the built-in virtual AKD), 'sim:N' (N of them), either with options joined by '&' after "
        "'?': 'missed=late' (F125 after more than seven frames missed, judged by time as the real drive: the "
        "default), 'missed=warn' (judged so, but a would-be F125 is counted and warned of, not raised) or "
        "'missed=lost' (only frames lost on the line count), 'pace=real' (AL requests and mailbox answered as "
        "slowly as the real drive: the default) or 'pace=immediate'; 'udp://HOST:PORT' "
        "(akd-sim --udp), or the name of the network interface the drive is wired to (needs CAP_NET_RAW), "
        "optionally with '?busy_poll=US' (0..=1000 µs) to busy-poll for each returning frame.",
    ),
    Spec(
        "joints",
        [],
        "Names of the joints on the bus, each with its own block joints.<name>.* of the joint parameters (slave, "
        "mode, mapping, units, limits, latches, fault reset, command time-out), whose defaults are the top-level "
        "values; its topics and services go under ~/<name>/. Empty: one joint, joint_name, with the top-level joint "
        "parameters and its topics and services under ~/. A name is letters, digits and single underscores, a "
        "letter first.",
    ),
    Spec(
        "devices",
        [],
        "Names of the devices on the line beside the drives (terminals: an EK1100's EL1004 inputs, EL2004 outputs), "
        "each with its block devices.<name>.slave (its position on the bus) and devices.<name>.product (what it must "
        "be, checked before anything goes to Op). Each device's channels, named after its PDO entries, are on "
        "~/<name>/io (akd_ros/DeviceIO) and set by name through ~/set_outputs. A name is letters, digits and single "
        "underscores, a letter first, and no joint's.",
    ),
    Spec(
        "fault_reaction",
        "all",
        "What a fault on one joint's drive does to the others: 'all' quick-stops them in the same cycle (as an arm "
        "needs) and switches the devices' outputs off until they are set again, 'joint' leaves them as they are.",
        choices=FAULT_REACTIONS,
    ),
    Spec(
        "slave",
        0,
        "Position of the drive on the bus, counted from 0 nearest the master; in a joint's block its default is the "
        "joint's place in joints.",
        0,
        65535,
        per_joint=True,
    ),
    Spec(
        "alias",
        -1,
        "Station alias of the drive (SII word 4, set with the drive's FBUS.PARAM03); when >= 0 it "
        "finds the drive instead of slave.",
        -1,
        65535,
        per_joint=True,
    ),
    Spec(
        "cycle_time",
        0.001,
        "Period of the EtherCAT cycle in seconds (the AKD takes 250 µs to 10 ms).",
        *CYCLE_TIME_RANGE,
    ),
    Spec(
        "dc",
        "auto",
        "Distributed clocks. 'on': SYNC0 at the cycle time and FBUS.PARAM02 = 1, the drive's PLL follows SYNC0 "
        "(as TwinCAT runs the AKD; FBUS.PARAM02 is written only where the drive's SDO information names the object "
        "so), the clocks' drift compensated every cycle; 'off': SYNC0 off, the drive follows "
        "each frame's SM2 event; 'auto': on for a network interface, off for 'sim', 'sim:N' and 'udp://', where a "
        "frame's timing is the host's scheduling and the socket's, not the wire's.",
        choices=tuple(DC_CHOICES),
    ),
    Spec(
        "dc_shift",
        0.0,
        "With distributed clocks: SYNC0 moved from the cycle boundary, seconds (negative: earlier); "
        "less than one cycle_time either way.",
        -CYCLE_TIME_RANGE[1],
        CYCLE_TIME_RANGE[1],
    ),
    Spec(
        "mode",
        "interpolated_position",
        "Mode of operation at start-up (0x6060); ~/set_mode changes it.",
        choices=tuple(MODES),
        per_joint=True,
        why_not=_native.MODES_NOT_OFFERED,
    ),
    Spec(
        "mapping",
        "default",
        "PDO mapping: 'default', 'io' (the drive's own I/O with every mode's command but interpolated position's), "
        "fixed mappings 'RX/TX' such as '0x1724/0x1B26', or 'flexible' (then mapping.rx and mapping.tx).",
        per_joint=True,
    ),
    Spec(
        "mapping.rx",
        [],
        "With mapping 'flexible': the RxPDOs (set-points), one string per PDO of entries "
        "'INDEX:SUB/BITS' separated by spaces, e.g. '0x6040:00/16 0x60C1:01/32'.",
        per_joint=True,
    ),
    Spec("mapping.tx", [], "With mapping 'flexible': the TxPDOs (actual values), as mapping.rx.", per_joint=True),
    Spec("joint_name", "akd_axis", "Name of the joint in joint_states and in the package's messages."),
    Spec("counts_per_revolution", 2**20, "Feedback counts per motor revolution.", 1, 2**31 - 1, per_joint=True),
    Spec("gear_ratio", 1.0, "Motor revolutions per load revolution.", 1e-9, 1e9, per_joint=True),
    Spec(
        "direction",
        1,
        "+1 when the load turns with the motor's positive sense, -1 against it.",
        choices=(1, -1),
        per_joint=True,
    ),
    Spec("offset", 0.0, "Load position at motor count 0: rad (m on a linear axis).", per_joint=True),
    Spec(
        "axis",
        "rotary",
        "'rotary' (rad, rad/s, N·m) or 'linear' (m, m/s, N).",
        choices=("rotary", "linear"),
        per_joint=True,
    ),
    Spec(
        "lead",
        0.0,
        "Linear axis only: metres of travel per load revolution (0 on a rotary axis).",
        0.0,
        1e6,
        per_joint=True,
    ),
    Spec(
        "peak_torque",
        3.0,
        "The drive's peak torque at the motor in N·m, which torque command 100 % means.",
        1e-9,
        1e6,
        per_joint=True,
    ),
    Spec("limits.min_position", -_INF, "Lowest position command, rad (m); -.inf for none.", per_joint=True),
    Spec("limits.max_position", _INF, "Highest position command, rad (m); .inf for none.", per_joint=True),
    Spec(
        "limits.max_velocity",
        _INF,
        "Largest velocity magnitude of any motion the node commands, rad/s (m/s): velocity commands, trajectories "
        "(every point and the path interpolated between them) and, in a cyclic position mode, the step of a position "
        "command within one cycle; .inf for none.",
        per_joint=True,
    ),
    Spec(
        "limits.max_acceleration",
        _INF,
        "Largest acceleration magnitude of a trajectory (every point and the path between them; where set, a "
        "trajectory must not step its velocity: give velocities at every point and end at rest) and of a position "
        "command's step in a cyclic position mode, rad/s² (m/s²); .inf for none.",
        per_joint=True,
    ),
    Spec("limits.max_torque", _INF, "Largest torque command magnitude, N·m (N); .inf for none.", per_joint=True),
    Spec(
        "limits.policy",
        "refuse",
        "A command past a limit is refused, or clamped to the limit.",
        choices=("refuse", "clamp"),
        per_joint=True,
    ),
    Spec("joint_states_rate", 100.0, "Rate of /joint_states in Hz.", 1.0, 1000.0),
    Spec("status_rate", 10.0, "Rate of ~/status in Hz.", 0.1, 100.0),
    Spec("diagnostics_rate", 1.0, "Rate of /diagnostics in Hz.", 0.1, 10.0),
    Spec(
        "io_rate",
        10.0,
        "Rate in Hz at which each joint's ~/io (akd_ros/DriveIO: its drive's own I/O) is published, besides once at "
        "each change of its digital inputs or hardware enable, stamped with the cycle that showed it.",
        0.1,
        1000.0,
    ),
    Spec(
        "io.analog_scale",
        ANALOG_VOLTS_PER_COUNT,
        "Volts per count of the drive's analog input 0x3470:04 and analog output 0x3470:03. The manuals give no "
        "scaling; the default assumes ±10 V over the 16-bit range: check it against the drive (WorkBench).",
        1e-9,
        1.0,
        per_joint=True,
    ),
    Spec(
        "latch.arm",
        [],
        "Latches armed at activate, each 'CHANNEL/EDGE' with channel 1 or 2 and edge rising "
        "or falling, e.g. ['1/rising', '2/falling'].",
        per_joint=True,
    ),
    Spec(
        "fault_reset",
        "manual",
        "'manual': a fault stays until ~/reset_fault; 'auto_once': each fault is reset "
        "once automatically (the drive is left disabled, never re-enabled).",
        choices=FAULT_RESET_POLICIES,
        per_joint=True,
    ),
    Spec(
        "command_timeout",
        0.5,
        "Seconds without a velocity or torque command, while that command is not zero, "
        "after which command_timeout_policy acts; 0 for never.",
        0.0,
        60.0,
        per_joint=True,
    ),
    Spec(
        "command_timeout_policy",
        "hold",
        "'hold': halt (controlword bit 8) and stay enabled until the next "
        "command; 'quick_stop': quick stop, ~/enable to go on.",
        choices=COMMAND_TIMEOUT_POLICIES,
        per_joint=True,
    ),
    Spec(
        "homing.method",
        "drive",
        "How the joint is referenced. 'drive': ~/home runs the homing the drive is set up for (on the AKD its HOME.* "
        "parameters, set in WorkBench: the EtherCAT manual names no CoE object for them, so the node writes none), "
        "in the cycle thread; the joint is homed once the drive reports homing attained, until its drive is "
        "power-cycled or lost. 'none': an absolute encoder, or an axis referenced otherwise; homed from the start.",
        choices=("drive", "none"),
        per_joint=True,
    ),
    Spec(
        "homing.required",
        False,
        "Whether the joint must be homed before it moves: position commands, ~/joint_commands naming it and "
        "trajectories through it are refused, naming the joint, while it is not homed. Velocity and torque commands "
        "are not held back (homing itself may need a jog to leave a limit switch).",
        per_joint=True,
    ),
    Spec(
        "homing.timeout",
        30.0,
        "Seconds a homing may take from its start to homing attained; past them the drive is halted and the joint "
        "reported timed out.",
        0.1,
        3600.0,
        per_joint=True,
    ),
    Spec(
        "homing.sequence",
        "together",
        "How ~/home homes several joints: 'together' starts them all at once; 'one_by_one' homes them in the order "
        "of the goal (of joints when it names none), each after the last attained, and stops at the first that fails.",
        choices=("together", "one_by_one"),
    ),
    Spec(
        "constraints.trajectory",
        0.0,
        "~/follow_joint_trajectory's default path tolerance for the joint, rad (m): while a goal runs, the cycle "
        "thread compares the actual position every cycle with the set-point of the cycle before; a larger error stops "
        "the joints (braking at trajectory.stop_deceleration) and ends the goal PATH_TOLERANCE_VIOLATED. A goal's "
        "path_tolerance overrides it (as joint_trajectory_controller's constraints.<joint>.trajectory). 0: not judged.",
        0.0,
        1e6,
        per_joint=True,
    ),
    Spec(
        "constraints.goal",
        0.0,
        "~/follow_joint_trajectory's default goal tolerance for the joint, rad (m): from the last point's time on, the "
        "goal succeeds once every joint's actual position is within it of the last point (and within "
        "constraints.stopped_velocity_tolerance of rest); past constraints.goal_time it ends GOAL_TOLERANCE_VIOLATED. "
        "A goal's goal_tolerance overrides it (as joint_trajectory_controller's constraints.<joint>.goal). 0: not "
        "judged.",
        0.0,
        1e6,
        per_joint=True,
    ),
    Spec(
        "constraints.stopped_velocity_tolerance",
        0.0,
        "~/follow_joint_trajectory's default goal velocity tolerance for the joint, rad/s (m/s): how fast it may "
        "still move when the goal is judged (as joint_trajectory_controller's constraints.stopped_velocity_tolerance). "
        "0: not judged.",
        0.0,
        1e6,
        per_joint=True,
    ),
    Spec(
        "constraints.goal_time",
        1.0,
        "~/follow_joint_trajectory's default goal time tolerance, s: how long past the last point's time the joints "
        "may take to come within their goal tolerances before the goal ends GOAL_TOLERANCE_VIOLATED. A goal's "
        "goal_time_tolerance overrides it where not 0. 0: judged at the last point's time, without waiting "
        "(joint_trajectory_controller waits without end there instead; a driver should not).",
        0.0,
        3600.0,
    ),
    Spec(
        "trajectory.stop_deceleration",
        10.0,
        "Deceleration, rad/s² (m/s²), at which a ~/follow_joint_trajectory goal that is canceled or strays past its "
        "path tolerance brings the joint from its set-point in force to a standstill, in the cycle thread (the "
        "velocity falls linearly to 0, never a jump). Set it within what the axis can do.",
        1e-3,
        1e9,
        per_joint=True,
    ),
    Spec(
        "follow_joint_trajectory.feedback_rate",
        20.0,
        "Rate in Hz of ~/follow_joint_trajectory's feedback (desired, actual and error of each joint of the goal).",
        0.1,
        1000.0,
    ),
    Spec(
        "eoe.ip",
        "",
        "The drive's IP address and prefix (A.B.C.D/N), given it by EoE Set IP Parameter at configure so that its "
        "IP stack answers there (eoe.tap or akd-eoe bridge a machine to it); '' gives none.",
        per_joint=True,
    ),
    Spec(
        "eoe.tap",
        "",
        "Name of a TAP interface (up to 15 characters, e.g. akd-eoe0) the node opens at configure and bridges to the "
        "EoE of every joint with an eoe.ip, so that the machine reaches the drives' addresses (ping, WorkBench); "
        "needs CAP_NET_ADMIN, without which the node warns and runs without it; closed at cleanup and shutdown. A "
        "name without '/', ':' or blanks, '%d' in it numbered by the kernel; needs at least one joint with eoe.ip. "
        "'' for none.",
    ),
    Spec("eoe.host", "", "The TAP interface's own address and prefix (A.B.C.D/N), '' for none."),
    Spec(
        "rt.priority",
        0,
        "SCHED_FIFO priority of the cycle thread, 1..99; 0 for the normal scheduler. Where the system does not permit "
        "it (no CAP_SYS_NICE, an RLIMIT_RTPRIO below it) the node says so in one warning and cycles on the normal "
        "scheduler.",
        0,
        99,
    ),
    Spec("rt.cpu", -1, "CPU the cycle thread is bound to; -1 for any.", -1, 1023),
    Spec(
        "rt.lock_memory",
        False,
        "Lock the process's memory (mlockall) so the cycle never waits on paging; where refused (no CAP_IPC_LOCK or "
        "RLIMIT_MEMLOCK), the node warns and runs without it.",
    ),
    Spec(
        "rt.cpu_latency_us",
        -1,
        "Hold every CPU's wake-up latency from idle at this many µs while the cycle runs (PM QoS, "
        "/dev/cpu_dma_latency, as cyclictest does), so that an idle CPU does not sleep too deeply to wake the cycle on "
        "time; needs write access to /dev/cpu_dma_latency (root), without which the node warns and runs without it. "
        "-1 leaves it to the system.",
        -1,
        1_000_000,
    ),
    Spec(
        "rt.pipelined",
        False,
        "Send each cycle's frame without waiting for it and take its return at the next wake-up, as the IgH "
        "master's cycles do: the cycle never waits for the round trip (less CPU, no busy poll needed, a lost frame "
        "costs no time) and writes its outputs from inputs as old as when waiting; what it reads (joint states, "
        "status) is published one cycle_time later.",
    ),
    Spec(
        "record.enabled",
        False,
        "Record the node's topics, its commands and every cycle to a rosbag2 bag (MCAP), from configure to cleanup.",
    ),
    Spec("record.folder", "bags", "Folder the bags go into, each named by the date and time it was opened."),
    Spec(
        "record.decimation",
        1,
        "Record every n-th cycle on ~/cycle; 0 records none (the black box keeps them).",
        0,
        1_000_000,
    ),
    Spec(
        "record.black_box_seconds",
        5.0,
        "Seconds of every cycle kept in memory and written to ~/black_box at a fault; 0 for none.",
        0.0,
        600.0,
    ),
    Spec(
        "live_view.port",
        0,
        "Serve a live view of everything the node publishes to Foxglove (its WebSocket protocol) on this TCP port, "
        "8765 being Foxglove's default; 0 for none. View only: clients can subscribe, never publish, call a service "
        "or set a parameter.",
        0,
        65535,
    ),
    Spec(
        "live_view.address",
        "127.0.0.1",
        "The address the live view listens on (an IPv4 or IPv6 address of this machine): 127.0.0.1 lets only this "
        "machine watch; 0.0.0.0 (or ::) every network, to watch from another machine.",
    ),
    Spec(
        "doors",
        ["observe", "operate"],
        "Which roles' doors the node has (docs/howto/access.md): observe (the topics it publishes), operate (the "
        "command topics, enable, disable, reset_fault, quick_stop, set_mode, arm_latch, set_outputs, sdo_read, the "
        "trajectories and actions) and configure (sdo_write). A door of a role not named does not exist on any "
        "transport; observe is always needed. Each request at an operating or configuring door is recorded on "
        "~/access.",
    ),
    Spec("autostart", True, "Walk the lifecycle to active at start-up (configure, then activate)."),
    Spec("enable_on_start", False, "Enable the power stage after activate (Operation enabled)."),
    Spec(
        "transport",
        "rclpy",
        "The middleware: 'rclpy' (DDS; where rclpy does not import and the file does not say, 'zenoh'), 'zenoh' "
        "(rmw_zenoh's wire format, with no ROS install needed) or 'both' (every topic and service on each).",
        choices=TRANSPORTS,
    ),
    Spec(
        "zenoh.config",
        "",
        "Over Zenoh: a Zenoh JSON5 configuration file for the session instead of rmw_zenoh's default (peer mode, a "
        "router at tcp/localhost:7447, multicast scouting off); empty for the default.",
    ),
    Spec(
        "zenoh.connect",
        [],
        "Over Zenoh: the endpoints the session connects to, e.g. ['tcp/192.168.1.10:7447'], instead of the "
        "default's or the file's; empty to keep those.",
    ),
)
"""Every parameter of akd_node; the documentation's reference of parameters is generated from it, in this order."""
SPECS = {spec.name: spec for spec in SCHEMA}
"""SCHEMA by parameter name."""
IO_NAME_SPECS: tuple[Spec, ...] = (
    Spec(
        "io.inputs.<name>",
        1,
        "Your name for one of the drive's digital inputs: its number, 1..7 as the AKD numbers them; the name is what "
        "~/io, /diagnostics and the bags show. Per joint (joints.<joint>.io.inputs.<name>) or for every joint.",
        1,
        7,
    ),
    Spec(
        "io.outputs.<name>",
        1,
        "Your name for one of the drive's digital outputs: its number, 1..2 as the AKD numbers them; ~/set_outputs "
        "takes the name. Per joint (joints.<joint>.io.outputs.<name>) or for every joint.",
        1,
        2,
    ),
)
"""The families of parameters that name a joint's inputs and outputs: each name given is a parameter of its own."""
DEVICE_SPECS: tuple[Spec, ...] = (
    Spec(
        "slave",
        -1,
        "Position of the device on the bus, counted from 0 nearest the master (akd-scan LINK lists them); it must be "
        "given.",
        -1,
        65535,
    ),
    Spec(
        "product",
        "",
        "What the device at slave must be: its order number as its SII gives it (akd-scan shows it), e.g. EL2004, "
        "compared without regard to case before anything goes to Op; '' checks nothing.",
    ),
)
"""The parameters of each device's block, devices.<name>.<parameter>."""
_IO_NAME = re.compile(r"(?:joints\.(?P<joint>[^.]+)\.)?io\.(?P<kind>inputs|outputs)\.(?P<name>[^.]+)")


def joint_specs(joints: list[str], top: dict[str, object]) -> list[Spec]:
    """The parameters of each joint's block, with the top-level values `top` as defaults (slave: the joint's place in
    `joints`)."""
    return [
        spec.of_joint(joint, position if spec.name == "slave" else top[spec.name])
        for position, joint in enumerate(joints)
        for spec in SCHEMA
        if spec.per_joint
    ]


JOINT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]*(_[A-Za-z0-9]+)*")
"""A joint name of `joints`: one ROS name token (letters, digits, single underscores inside; a letter first), so that
~/<joint>/ is a valid namespace and joints.<name>.* a valid parameter name."""


def _refuse_non_tokens(kind: str, names: list[str], examples: str) -> None:
    """ParameterError for the first of parameter `kind`s' `names` that is not a ROS name token (`JOINT_NAME`)."""
    for name in names:
        if not JOINT_NAME.fullmatch(name):
            raise ParameterError(
                f"parameter {kind}s: {name!r} is not a {kind} name; allowed: letters, digits and single underscores "
                f"between them, a letter first (e.g. {examples})"
            )


def check_joint_names(joints: list[str]) -> list[str]:
    """`joints` if every name is a ROS name token and none is given twice; ParameterError otherwise."""
    _refuse_non_tokens("joint", joints, "joint_1, shoulder_pan")
    twice = sorted({j for j in joints if joints.count(j) > 1})
    if twice:
        raise ParameterError(f"parameter joints names {', '.join(twice)} more than once; each joint once")
    return joints


def device_specs(devices: list[str]) -> list[Spec]:
    """The parameters of each device's block (devices.<name>.slave, devices.<name>.product)."""
    return [
        replace(spec, name=f"devices.{device}.{spec.name}", description=f"Device {device}: {spec.description}")
        for device in devices
        for spec in DEVICE_SPECS
    ]


def check_device_names(devices: list[str], joints: list[str]) -> list[str]:
    """`devices` if every name is a ROS name token, none is given twice and none is a joint's (their topics would be
    one); ParameterError otherwise."""
    _refuse_non_tokens("device", devices, "gripper_valves, inputs_1")
    twice = sorted({d for d in devices if devices.count(d) > 1} | (set(devices) & set(joints)))
    if twice:
        raise ParameterError(
            f"parameter devices names {', '.join(twice)} more than once (or as a joint); each device once, "
            "under a name of its own"
        )
    return devices


def refuse_single_joint_parameters(named: dict[str, object], joints: list[str]) -> None:
    """Refuses joint_name, slave and alias among the `named` parameters when `joints` names the joints."""
    given_once = sorted(n for n in ("joint_name", "slave", "alias") if n in named)
    if joints and given_once:
        raise ParameterError(
            f"parameter {', '.join(given_once)} applies to a file without joints; with joints, each joint is "
            "named in joints and found by joints.<name>.slave (default: its place in joints) or "
            "joints.<name>.alias"
        )


def io_name_specs(named: dict[str, object], joints: list[str]) -> list[Spec]:
    """The parameter of each input or output name among the `named` parameters (io.inputs.<name>,
    io.outputs.<name>, and the same in the block of a joint of `joints`), to check and declare as any other; a name
    that is not a ROS name token, or a block of no joint, is left out (and so refused as unknown)."""
    family = {"inputs": IO_NAME_SPECS[0], "outputs": IO_NAME_SPECS[1]}
    specs = []
    for name in named:
        found = _IO_NAME.fullmatch(name)
        if found is None or not JOINT_NAME.fullmatch(found["name"]):
            continue
        if found["joint"] is not None and found["joint"] not in joints:
            continue
        template = family[found["kind"]]
        specs.append(replace(template, name=name, description=template.description.replace("<name>", found["name"])))
    return specs


def io_names(values: dict[str, object], joint: str | None, kind: str) -> dict[str, int]:
    """The names `values` gives the joint's inputs or outputs (`kind`): every joint's (io.<kind>.<name>) and, for
    `joint`, its block's, which win; each checked (a number the AKD has)."""
    specs = io_name_specs(values, [] if joint is None else [joint])
    names = {}
    for prefix in ("", f"joints.{joint}.") if joint is not None else ("",):
        for spec in specs:
            if spec.name.startswith(f"{prefix}io.{kind}."):
                names[spec.name.rsplit(".", 1)[1]] = spec.check(values[spec.name])
    return names


def refuse_unknown(unknown: list[str], joints: list[str], devices: list[str] = ()) -> None:
    """Refuses the `unknown` parameter names, if any, naming what the node has with `joints` and `devices`."""
    if unknown:
        raise ParameterError(
            f"unknown parameter {', '.join(sorted(unknown))}; the parameters are: {', '.join(SPECS)}, for each "
            f"joint of joints ({', '.join(joints) or 'none given'}) joints.<name>.<one of "
            f"{', '.join(s.name for s in SCHEMA if s.per_joint)}>, and for each device of devices "
            f"({', '.join(devices) or 'none given'}) devices.<name>.<one of {', '.join(s.name for s in DEVICE_SPECS)}>"
        )


def check_names(named: dict[str, object]) -> None:
    """Refuses, as `akd_ros.node.ros_parameters.declare` does, names given that the node does not have: neither in
    SCHEMA nor in the block of a joint of `joints` (rclpy's qos_overrides.* aside), and joint_name, slave or alias
    beside joints; ParameterError."""
    joints = check_joint_names(SPECS["joints"].check(named.get("joints", [])))
    devices = check_device_names(SPECS["devices"].check(named.get("devices", [])), joints)
    refuse_single_joint_parameters(named, joints)
    blocks = {spec.name for spec in joint_specs(joints, {spec.name: spec.default for spec in SCHEMA})}
    blocks |= {spec.name for spec in io_name_specs(named, joints)}
    blocks |= {spec.name for spec in device_specs(devices)}
    refuse_unknown(
        [n for n in named if n not in SPECS and n not in blocks and not n.startswith("qos_overrides.")],
        joints,
        devices,
    )


def check_interface_address(name: str, text: str) -> str | None:
    """Parameter `name`'s `text` as an IPv4 address with its prefix (A.B.C.D/N), None for ''; ParameterError."""
    if not text:
        return None
    try:
        # The prefix is needed: a /32 address has no route back to the machine that talks to it.
        if "/" not in text:
            raise ValueError(text)
        return str(ipaddress.IPv4Interface(text))
    except ValueError:
        raise ParameterError(
            f"parameter {name} must be an IPv4 address with its prefix such as 192.168.0.10/24, or '', got {text!r}"
        ) from None


def check_doors(roles: list[str]) -> tuple[str, ...]:
    """The roles the doors parameter opens, in DOOR_ROLES' order; ParameterError naming the allowed ones."""
    unknown = [r for r in roles if r not in DOOR_ROLES]
    if unknown or "observe" not in roles or len(set(roles)) != len(roles):
        why = (
            f"{unknown[0]!r} is not a role"
            if unknown
            else "observe is missing"
            if "observe" not in roles
            else "a role is named twice"
        )
        raise ParameterError(
            f"parameter doors must name roles among {', '.join(DOOR_ROLES)}, observe among them, each once; got "
            f"{roles!r}: {why}"
        )
    return tuple(r for r in DOOR_ROLES if r in roles)


def check_live_view(address: str, port: int) -> tuple[str, int] | None:
    """(live_view.address, live_view.port) checked, None for port 0; ParameterError for an address that is not an IP
    address. Whether the port is free is known only when the node opens it, before the bus."""
    try:
        ipaddress.ip_address(address)
    except ValueError:
        raise ParameterError(
            "parameter live_view.address must be an IPv4 or IPv6 address of this machine such as 127.0.0.1 (only this "
            f"machine), 0.0.0.0 or :: (every network), got {address!r}"
        ) from None
    return (address, port) if port else None


def check_link(link: str) -> str:
    """`link` if the node can open it: a link spec the extension accepts (`_native.LINK_FORMS`) that, where it names a
    network interface, names one of this machine."""

    try:
        spec = _native.parse_link(link)
    except _native.ConfigError as e:
        raise ParameterError(f"parameter {e}") from None
    interfaces = sorted(name for _, name in socket.if_nameindex())
    if spec.kind == "interface" and spec.name not in interfaces:
        raise ParameterError(
            f"parameter link: network interface {link!r} does not exist; allowed: {_native.LINK_FORMS} of this "
            f"machine ({', '.join(interfaces)})"
        )
    return link


def parse_mapping(mapping: str, rx: list[str], tx: list[str], prefix: str = "") -> tuple[object, object] | None:
    """(rx, tx) in the form `_native.Master.configure_pdo` takes, None for 'default'; raises ParameterError naming
    the parameters with `prefix`."""
    allowed = "'default', 'io', 'RX/TX' fixed mappings such as '0x1724/0x1B26', or 'flexible' (with mapping.rx/.tx)"
    if (rx or tx) and mapping != "flexible":
        raise ParameterError(
            f"parameters {prefix}mapping.rx and {prefix}mapping.tx apply to mapping 'flexible' only; "
            f"{prefix}mapping is {mapping!r}"
        )
    if mapping == "default":
        return None
    if mapping == "io":
        from akd_ros import _native

        return _native.IO_MAPPING
    if mapping == "flexible":
        if not rx or not tx:
            raise ParameterError(
                f"parameter {prefix}mapping 'flexible' needs both {prefix}mapping.rx and {prefix}mapping.tx, each a "
                "list of PDOs such as ['0x6040:00/16 0x60C1:01/32']"
            )
        return [_pdo(f"{prefix}mapping.rx", p) for p in rx], [_pdo(f"{prefix}mapping.tx", p) for p in tx]
    found = re.fullmatch(r"0x([0-9A-Fa-f]{4})/0x([0-9A-Fa-f]{4})", mapping)
    if not found:
        raise ParameterError(f"parameter {prefix}mapping {mapping!r} is not a mapping; allowed: {allowed}")
    return int(found[1], 16), int(found[2], 16)


def _pdo(name: str, text: str) -> list[int]:
    """One PDO's entries as 0xIIIISSBB from 'INDEX:SUB/BITS ...' (the extension's entry syntax)."""
    from akd_ros import _native

    entries = []
    for word in text.split():
        try:
            entries.append(_native.parse_pdo_entry(word))
        except ValueError as e:
            raise ParameterError(f"parameter {name}: {e}") from None
    if not entries:
        raise ParameterError(f"parameter {name}: an empty PDO; each string lists entries INDEX:SUB/BITS")
    return entries


def check_mapping(mapping: tuple[object, object], prefix: str = "") -> None:
    """Checks `mapping` against the AKD's mapping rules (the extension's, without a drive); ParameterError with the
    reason (and the allowed fixed mappings) when a drive would refuse it."""
    from akd_ros import _native

    try:
        _native.check_mapping(*mapping)
    except _native.PdoError as e:
        raise ParameterError(f"parameter {prefix}mapping: {e}") from None


def parse_limits(values: dict[str, object], prefix: str = "") -> Limits:
    """The Limits of the limits.* parameters (an infinite one is no limit), named with `prefix` in messages."""

    def bound(name: str) -> float | None:
        value = values["limits." + name]
        if math.isnan(value):
            raise ParameterError(f"parameter {prefix}limits.{name} must be a number or .inf/-.inf for none, got NaN")
        return None if math.isinf(value) else value

    try:
        return Limits(
            bound("min_position"),
            bound("max_position"),
            bound("max_velocity"),
            bound("max_torque"),
            values["limits.policy"],
            bound("max_acceleration"),
        )
    except ValueError as e:
        raise ParameterError(f"parameters {prefix}limits.*: {e}") from None


def parse_latches(items: list[str], prefix: str = "") -> tuple[tuple[int, str], ...]:
    """(channel, edge) of each 'CHANNEL/EDGE' of latch.arm; raises ParameterError naming it with `prefix`."""
    latches = []
    for item in items:
        channel, _, edge = item.partition("/")
        if channel not in ("1", "2") or edge not in EDGES:
            raise ParameterError(
                f"parameter {prefix}latch.arm: {item!r} is not CHANNEL/EDGE; allowed: 1/rising, 1/falling, 2/rising, "
                "2/falling"
            )
        latches.append((int(channel), edge))
    return tuple(latches)
