"""akd_node with the drives' own I/O, seen from another process through real rclpy: inputs flipped on the virtual AKD
shown on ~/io with the integrator's names, outputs set through ~/set_outputs read back from the drive, a limit switch
that stops a move and is named by /diagnostics, a hardware enable low named too, and refusals of one line that change
nothing.

The drives are an `akd-sim --udp --count 2` process whose stdin flips their inputs, the node `akd_node --ros-args
--params-file FILE` with joint a on the `io` mapping and joint b on the default one (which carries no outputs), and
this process the ROS client (Fast DDS, a ROS_DOMAIN_ID of the module's own). A second node, of one joint, records every
cycle: its bag tells in which cycle the drive's process image showed an input change, and in which ~/io did. Every wait
is bounded; the processes are always ended.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from akd_ros.msg import DriveIO
from support.ros import COUNTS_PER_RAD, Participant, module_domain, node_on_sim

DOMAINS = range(84, 90)
"""ROS_DOMAIN_IDs of this module (others: 0-30, 60-70, 100-232); the recorded node takes the next one."""
NODE = "/akd_node/"
CSP = "cyclic_synchronous_position"
ANALOG_STEP = 10.0 / 32767
"""One count of the analog objects, V."""

PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    mode: cyclic_synchronous_position
    io_rate: 20.0
    diagnostics_rate: 5.0
    command_timeout: 1.0
    joints: [a, b]
    joints.a.mapping: io
    joints.a.io.inputs.part_present: 3
    joints.a.io.outputs.lamp: 2
"""

RECORDED = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    mode: cyclic_synchronous_position
    mapping: io
    joint_name: a
    io_rate: 1.0
    io:
      inputs: {{part_present: 3}}
    record.enabled: true
    record.folder: {folder}
    record.black_box_seconds: 0.0
"""


class Client(Participant):
    """Each joint's ~/io, /joint_states and /diagnostics collected; commands and service calls."""

    def __init__(self, domain: int, joints: list[str]):
        super().__init__(domain, "akd_node_io_test")
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.prefix = {j: f"{NODE}{j}/" if len(joints) > 1 else NODE for j in joints}
        topics = {f"{self.prefix[j]}io": DriveIO for j in joints} | {
            "/joint_states": JointState,
            "/diagnostics": DiagnosticArray,
        }
        for topic, kind in topics.items():
            self.received[topic] = []
            self.node.create_subscription(kind, topic, self.received[topic].append, qos)
        self.positions = {
            j: self.node.create_publisher(Float64, f"{self.prefix[j]}position_command", qos) for j in joints
        }

    def io(self, joint: str, done=lambda m: True, what: str = "~/io") -> DriveIO:
        """The first ~/io message of `joint` from now on for which `done(message)`."""
        topic = f"{self.prefix[joint]}io"
        seen = len(self.received[topic])

        def arrived():
            return next((m for m in self.received[topic][seen:] if done(m)), None)

        self.spin_until(arrived, f"{what} of {joint}")
        return arrived()

    def position(self, joint: str) -> float:
        count = len(self.received["/joint_states"])
        self.spin_until(lambda: len(self.received["/joint_states"]) > count, "/joint_states")
        message = self.received["/joint_states"][-1]
        return message.position[message.name.index(joint)]

    def status(self, joint: str, done, what: str) -> DiagnosticStatus:
        """The first /diagnostics status of `joint` from now on for which `done(status)`."""
        return super().status(f"akd_node: {joint}", done, what)

    def trigger(self, name: str) -> Trigger.Response:
        return self.call(Trigger, name)

    def move(self, joint: str, start: float, distance: float, seconds: float = 1.0) -> None:
        """Streams position commands from `start` by `distance` over `seconds`."""
        publisher = self.positions[joint]
        self.spin_until(lambda: publisher.get_subscription_count() > 0, f"the node's {joint} position_command")
        steps = int(seconds / 0.02)
        for i in range(1, steps + 1):
            publisher.publish(Float64(data=start + distance * i / steps))
            self.spin_for(0.02)


def named(message: DriveIO, name: str, kind: str = "input") -> bool:
    names, levels = (
        (message.input_names, message.named_inputs)
        if kind == "input"
        else (message.output_names, message.named_outputs)
    )
    return levels[list(names).index(name)]


def content(message: DriveIO) -> tuple:
    """What `message` says but for its stamp and cycle."""
    skipped = {"header", "cycle"}
    return tuple(
        tuple(value) if not isinstance(value := getattr(message, field), str | int | float | bool) else value
        for field in message.get_fields_and_field_types()
        if field not in skipped
    )


ros_domain = module_domain(DOMAINS)


@pytest.fixture(scope="module")
def run(ros_domain, tmp_path_factory):
    """akd-sim with two drives, the node of joints a and b on it, and the client once ~/a/io arrives."""
    folder = tmp_path_factory.mktemp("node_io")
    client_of = functools.partial(Client, joints=["a", "b"])
    with node_on_sim(PARAMS, folder, ros_domain, count=2, client_of=client_of, ready=f"{NODE}a/io") as run:
        yield run


def test_the_io_of_each_joint_is_published_with_what_its_mapping_carries(run):
    _, node, ros = run
    a, b = ros.io("a"), ros.io("b")
    assert (a.joint, a.digital_inputs_mapped, a.digital_outputs_mapped) == ("a", True, True)
    assert (list(a.input_names), list(a.output_names)) == (["part_present"], ["lamp"])
    assert len(a.inputs) == 7 and len(a.outputs) == 2 and not math.isnan(a.analog_input)
    assert a.hardware_enable == DriveIO.HARDWARE_ENABLE_HIGH
    # The default mapping carries the digital inputs only.
    assert (b.digital_inputs_mapped, b.digital_outputs_mapped, len(b.outputs)) == (True, False, 0)
    assert math.isnan(b.analog_input) and math.isnan(b.analog_output)
    assert (
        "I/O the mappings carry: a: digital inputs, analog input, digital outputs, analog output; b: digital inputs"
        in (node.output())
    )


def test_an_input_flipped_on_the_drive_shows_on_io_with_its_name(run):
    sim, _, ros = run
    before = ros.io("a")
    assert not named(before, "part_present")
    sim.command("input 0 3 high")
    seen = len(ros.received[f"{NODE}a/io"])
    high = ros.io("a", lambda m: named(m, "part_present"), "part_present high")
    assert high.inputs[2] and high.digital_inputs == 1 << 18 and high.cycle > before.cycle
    # The edge's own message (made by the crate from the cycle's event) and those it makes at io_rate after it say the
    # same but for their stamps and cycles.
    ros.spin_for(3 / 20.0)
    after = [m for m in ros.received[f"{NODE}a/io"][seen:] if named(m, "part_present")]
    assert len(after) >= 3, [m.cycle for m in after]
    assert len({content(m) for m in after}) == 1, {content(m) for m in after}
    # /diagnostics shows it by the name too.
    ros.status("a", lambda s: ("input part_present (3)", "high") in [(v.key, v.value) for v in s.values], "the name")
    sim.command("analog_input 0 -4")
    shown = ros.io("a", lambda m: abs(m.analog_input + 4.0) <= ANALOG_STEP, "the analog input")
    assert named(shown, "part_present")
    sim.command("input 0 3 low")
    ros.io("a", lambda m: not named(m, "part_present"), "part_present low")


def test_outputs_set_through_the_service_read_back_from_the_drive(run):
    sim, _, ros = run
    response = ros.set_outputs("a", ["lamp", "1"], [True, False], analog=2.5)
    assert response.success, response.message
    assert response.message == "a: output 1 low, output 2 high, analog output 2.5 V from the next cycle"
    ros.io("a", lambda m: named(m, "lamp", "output") and abs(m.analog_output - 2.5) <= ANALOG_STEP, "lamp on")
    drive = sim.state(0)
    assert drive["digital_outputs"] == [False, True] and abs(drive["analog_output"] - 2.5) <= ANALOG_STEP, drive
    response = ros.set_outputs("a", ["2"], [False])
    assert response.success, response.message
    ros.io("a", lambda m: not any(m.outputs), "lamp off")
    assert sim.state(0)["digital_outputs"] == [False, False]


def test_bad_requests_are_refused_in_one_line_and_change_nothing(run):
    sim, _, ros = run
    assert ros.set_outputs("a", ["1"], [True], analog=-1.0).success
    ros.io("a", lambda m: m.outputs[0], "output 1 on")
    before = sim.state(0)
    for joint, outputs, values, analog, refusal in (
        (
            "a",
            ["brake"],
            [True],
            None,
            "output 'brake' of joint a: allowed its names (lamp) or the AKD's output numbers 1, 2",
        ),
        ("a", ["3"], [True], None, "outputs refused: output 3: the AKD has digital outputs 1 to 2"),
        ("a", ["lamp"], [True], math.nan, "analog output refused: nan V; allowed a finite voltage within ±10 V"),
        ("a", [], [], 10.5, "analog output refused: 10.5 V; allowed a finite voltage within ±10 V"),
        ("a", ["lamp", "2"], [True, False], None, "output '2' of joint a (output 2) is given twice"),
        ("a", ["lamp"], [], None, "1 outputs with 0 values: give one value per output"),
        ("a", [], [], None, "nothing to set: give outputs with their values, or set_analog_output"),
        ("", ["1"], [True], None, "joint '' is not one of this node's joints: a, b"),
        (
            "b",
            ["1"],
            [True],
            None,
            "outputs refused: the mapping of b carries no digital outputs (0x60FE:01); mappings that do with mode "
            f"{CSP}: io, 0x1725/0x1B20",
        ),
        ("b", [], [], 1.0, f"no analog output (0x3470:03); mappings that do with mode {CSP}: io, 0x1725/0x1B20"),
    ):
        response = ros.set_outputs(joint, outputs, values, analog)
        assert not response.success and "\n" not in response.message, response.message
        assert response.message.startswith("outputs not set: ") and refusal in response.message, response.message
    after = sim.state(0)
    assert (after["digital_outputs"], after["analog_output"]) == (before["digital_outputs"], before["analog_output"])


def test_a_limit_switch_stops_a_move_toward_it_and_diagnostics_name_it(run):
    sim, _, ros = run
    assert ros.trigger("a/enable").success
    sim.command("switch 0 positive_limit on")
    ros.io("a", lambda m: m.positive_limit, "the positive limit switch")
    start = ros.position("a")
    ros.move("a", start, 0.5)
    ros.spin_for(0.3)
    assert ros.position("a") < start + 0.02, (start, ros.position("a"))
    status = ros.status("a", lambda s: "limit switch" in s.message, "/diagnostics naming the switch")
    assert status.level == DiagnosticStatus.WARN
    assert "positive limit switch active (0x60FD bit 1): the drive stops moves in the positive direction" in (
        status.message
    ), status.message
    # Away from the switch the joint moves.
    here = ros.position("a")
    ros.move("a", here, -0.5)
    ros.spin_until(lambda: ros.position("a") < here - 0.4, "the move away")
    sim.command("switch 0 positive_limit off")
    ros.status("a", lambda s: "limit switch" not in s.message, "/diagnostics without the switch")
    assert ros.trigger("a/disable").success


def test_a_hardware_enable_low_is_named_and_refuses_the_enable(run):
    sim, _, ros = run
    sim.command("hardware_enable 1 low")
    low = ros.io("b", lambda m: m.hardware_enable == DriveIO.HARDWARE_ENABLE_LOW, "the hardware enable low")
    assert low.joint == "b"
    status = ros.status("b", lambda s: "hardware enable low" in s.message, "/diagnostics naming the enable")
    assert status.level == DiagnosticStatus.WARN and "statusword bit 7" in status.message, status.message
    response = ros.trigger("b/enable")
    assert not response.success and "hardware enable input is low" in response.message, response.message
    sim.command("hardware_enable 1 high")
    ros.io("b", lambda m: m.hardware_enable == DriveIO.HARDWARE_ENABLE_HIGH, "the hardware enable high")
    assert ros.trigger("b/enable").success
    assert ros.trigger("b/disable").success


def test_an_input_change_is_on_io_within_two_cycles_of_the_drives_process_image(ros_domain, tmp_path):
    """The cycle whose recorded 0x6064 first shows the axis past a toggle is when the drive's process image showed the
    input change; ~/io's message of the change must name a cycle at most two later."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    params = RECORDED.replace("{folder}", str(tmp_path / "bags"))
    client_of = functools.partial(Client, joints=["a"])
    with node_on_sim(params, tmp_path, ros_domain + 1, client_of=client_of, ready=f"{NODE}io") as (sim, _, client):
        assert client.trigger("enable").success
        start = client.position("a")
        # Half a count past a whole count: there the rounded 0x6064 shows the crossing as the input does.
        edge = round((start + 0.2) * COUNTS_PER_RAD) + 0.5
        sim.command(f"toggles 0 3 {edge}")
        client.move("a", start, 0.4)
        client.io("a", lambda m: named(m, "part_present"), "part_present high")
        client.trigger("disable")
    store = get_typestore(Stores.ROS2_JAZZY)
    for msg in sorted((Path(__file__).resolve().parents[1] / "msg").glob("*.msg")):
        store.register(get_types_from_msg(msg.read_text(), f"akd_ros/msg/{msg.stem}"))
    (bag,) = (tmp_path / "bags").iterdir()
    with AnyReader([bag], default_typestore=store) as reader:
        wanted = [c for c in reader.connections if c.topic in (NODE + "cycle", NODE + "io")]
        messages = [(c.topic, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages(connections=wanted)]
    first = min(m.cycle for topic, m in messages if topic == NODE + "cycle" and m.position_counts >= edge)
    changes = [m for topic, m in messages if topic == NODE + "io" and named(m, "part_present")]
    assert changes, "no ~/io message with part_present high in the bag"
    # The first is the change's own message; those at io_rate are of later cycles.
    shown = min(m.cycle for m in changes)
    assert 0 <= shown - first <= 2, (first, shown)
