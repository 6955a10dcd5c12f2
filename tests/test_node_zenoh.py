"""akd_node with `transport: zenoh` in a Python without ROS, seen from an independent Zenoh session.

A Zenoh router in its own process listens on a loopback port the test picks; `akd-sim --count 2 --udp` serves two
virtual AKDs; the node runs as `akd_node --ros-args --params-file FILE` from `.venv-noros` (scripts/setup.sh makes it
without any ROS wheel; where it is missing, from `.venv`), with `tests/support/no_ros` on its path, which refuses
every ROS import (rclpy, rosidl, the message packages and akd_ros's generated ones), so it runs as on a controller
with no ROS install. This process talks to it over Zenoh only, as an rmw_zenoh node would: exact key
expressions, rmw_zenoh's attachments, liveliness tokens, and payloads decoded with rosbags.
"""

from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path

import pytest

from akd_ros.zenoh.types import Types
from akd_ros.zenoh.wire import Attachment, Entity, EntityKind, data_key_expr, dds_type_name, gid_of
from support.ros import COUNTS_PER_RAD, NodeProcess, Sim, node_command, stop
from support.waiting import wait_for
from support.zenoh import WAIT_S, liveliness_keys, zenoh_router, zenoh_session

REPO = Path(__file__).resolve().parents[1]
DOMAIN = 0
JOINTS = ["joint_1", "joint_2"]
JOINT_STATE = "sensor_msgs/msg/JointState"
TRIGGER = "std_srvs/srv/Trigger"

PARAMS = """\
akd_node:
  ros__parameters:
    transport: zenoh
    zenoh.connect: ["{endpoint}"]
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    rt.priority: 30
    mode: cyclic_synchronous_position
    joint_states_rate: 50.0
    joints: [joint_1, joint_2]
"""


@pytest.fixture(scope="module")
def types():
    return Types()


@pytest.fixture(scope="module")
def router():
    with zenoh_router() as endpoint:
        yield endpoint


@pytest.fixture(scope="module")
def peer(router):
    """The test's own Zenoh session, independent of the node's."""
    with zenoh_session(router) as session:
        yield session


class Collected:
    """Every joint_states sample the peer receives: (attachment, payload), from before the node starts."""

    def __init__(self, peer, types: Types) -> None:
        self.key = data_key_expr(DOMAIN, "/joint_states", dds_type_name(JOINT_STATE), types.rihs01(JOINT_STATE))
        self.samples: list[tuple[bytes | None, bytes]] = []
        self._lock = threading.Lock()
        self._subscriber = peer.declare_subscriber(self.key, self._on_sample)

    def _on_sample(self, sample) -> None:
        with self._lock:
            attachment = None if sample.attachment is None else sample.attachment.to_bytes()
            self.samples.append((attachment, sample.payload.to_bytes()))

    def taken(self) -> list[tuple[bytes | None, bytes]]:
        with self._lock:
            return list(self.samples)


@pytest.fixture(scope="module")
def node(peer, router, types, tmp_path_factory):
    """The simulator, the collector of joint_states (declared first, so it sees the first sample), and the node."""
    from support.netns import free_udp_port

    collected = Collected(peer, types)
    sim = Sim(free_udp_port(), count=len(JOINTS))
    path = tmp_path_factory.mktemp("zenoh") / "akd_node.yaml"
    path.write_text(PARAMS.format(endpoint=router, port=sim.port))
    node = NodeProcess(path, DOMAIN, without_ros=True)
    print(f"running {node.program}")
    process, log = node.process, node.log
    try:
        wait_for("joint_states over Zenoh", lambda: collected.taken() or process.poll() is not None, WAIT_S)
        assert process.poll() is None, "".join(log)
        yield sim, process, log, collected
    finally:
        stop(process)
        sim.stop()
        print("akd_node output:\n" + "".join(log))


def output(node) -> str:
    return "".join(node[2])


def entities(peer, *more: tuple[EntityKind, str]) -> list[Entity]:
    """The entities of the graph's liveliness tokens, once the node's own, its joint_states publisher and the `more`
    (kind, topic or service name) are among them: a query may reach the router before every token the node
    declared."""

    def listed():
        found = [Entity.parse(k) for k in liveliness_keys(peer, DOMAIN)]
        kinds = {(e.kind, e.topic.name if e.topic else e.node.name) for e in found}
        wanted = {(EntityKind.NODE, "akd_node"), (EntityKind.PUBLISHER, "/joint_states"), *more}
        return found if wanted <= kinds else None

    return wait_for("the node's liveliness tokens", listed, WAIT_S, 0.2)


def test_the_node_ran_without_any_ros_module(node):
    text = output(node)
    assert "active: publishing /joint_states of joint_1, joint_2" in text, text
    assert "Traceback" not in text


def test_joint_states_arrive_on_the_exact_key_decoded_by_rosbags(node, types):
    _, _, _, collected = node
    wait_for("three samples", lambda: len(collected.taken()) >= 3, WAIT_S)
    _, payload = collected.taken()[-1]
    message = types.from_cdr(payload, JOINT_STATE)
    assert list(message.name) == JOINTS and len(message.position) == 2
    assert collected.key == (
        "0/joint_states/sensor_msgs::msg::dds_::JointState_/"
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
    )


def test_every_sample_carries_rmw_zenohs_attachment(node, peer):
    _, _, _, collected = node
    wait_for("ten samples", lambda: len(collected.taken()) >= 10, WAIT_S)
    attachments = [Attachment.decode(a) for a, _ in collected.taken()]
    numbers = [a.sequence_number for a in attachments]
    assert numbers == list(range(1, len(numbers) + 1)), numbers[:20]
    stamps = [a.source_timestamp for a in attachments]
    assert stamps == sorted(stamps) and abs(stamps[-1] - time.time_ns()) < 60e9
    (gid,) = {a.gid for a in attachments}
    (token,) = [e for e in entities(peer) if e.kind is EntityKind.PUBLISHER and e.topic.name == "/joint_states"]
    assert gid == gid_of(token.liveliness_key())


def test_the_liveliness_tokens_name_the_node_its_topics_types_and_qos(node, peer, types):
    asserted = [
        (EntityKind.SUBSCRIPTION, "/akd_node/joint_commands"),
        (EntityKind.PUBLISHER, "/akd_node/joint_1/status"),
        (EntityKind.SERVICE, "/akd_node/enable"),
        (EntityKind.SERVICE, "/akd_node/joint_2/set_mode"),
    ]
    found = entities(peer, *asserted)
    (node_token,) = [e for e in found if e.kind is EntityKind.NODE]
    assert (node_token.node.name, node_token.node.namespace) == ("akd_node", "/")
    topics = {(e.kind, e.topic.name): e.topic for e in found if e.topic is not None}
    joint_states = topics[EntityKind.PUBLISHER, "/joint_states"]
    assert (joint_states.dds_type, joint_states.type_hash) == (dds_type_name(JOINT_STATE), types.rihs01(JOINT_STATE))
    assert joint_states.qos.depth == 10
    assert topics[EntityKind.SUBSCRIPTION, "/akd_node/joint_commands"].qos.depth == 100
    assert all(entity in topics for entity in asserted)


def call(peer, types, name: str, sequence_number: int, gid: bytes, domain: int = DOMAIN):
    """Calls the Trigger service `name` with rmw_zenoh's attachment; its reply."""
    key = data_key_expr(domain, name, dds_type_name(TRIGGER), types.rihs01(TRIGGER))
    request = types.to_cdr(types.message(f"{TRIGGER}_Request"), f"{TRIGGER}_Request")
    attachment = Attachment(sequence_number, time.time_ns(), gid).encode()
    replies = list(peer.get(key, payload=request, attachment=attachment, timeout=WAIT_S))
    assert len(replies) == 1 and replies[0].ok is not None, replies
    return replies[0].ok


def test_a_bus_wide_enable_is_answered_with_the_replys_attachment_right(node, peer, types):
    sim = node[0]
    gid = bytes(range(16))
    reply = call(peer, types, "/akd_node/enable", 7, gid)
    response = types.from_cdr(reply.payload.to_bytes(), f"{TRIGGER}_Response")
    assert response.success, response.message
    attachment = Attachment.decode(reply.attachment.to_bytes())
    assert (attachment.sequence_number, attachment.gid) == (7, gid)
    assert [sim.state(i)["state"] for i in range(2)] == ["Operation enabled"] * 2


def joint_commands_key(types, domain: int = DOMAIN) -> str:
    return data_key_expr(domain, "/akd_node/joint_commands", dds_type_name(JOINT_STATE), types.rihs01(JOINT_STATE))


def move_joint_1_over_zenoh(sim, peer, types, domain: int = DOMAIN) -> None:
    """Enables the drives by their service and moves joint_1 by 0.01 rad by joint_commands, both over Zenoh."""
    response = types.from_cdr(
        call(peer, types, "/akd_node/enable", 8, bytes(16), domain).payload.to_bytes(), f"{TRIGGER}_Response"
    )
    assert response.success, response.message
    start = sim.state(0)["position"] / COUNTS_PER_RAD
    target = start + 0.01
    gid = bytes(range(32, 48))
    for number in range(1, 21):
        message = types.message(JOINT_STATE, name=["joint_1"], position=[start + 0.01 * number / 20])
        payload = types.to_cdr(message, JOINT_STATE)
        attachment = Attachment(number, time.time_ns(), gid).encode()
        peer.put(joint_commands_key(types, domain), payload, attachment=attachment)
        time.sleep(0.02)
    wait_for("joint_1 at its target", lambda: abs(sim.state(0)["position"] - target * COUNTS_PER_RAD) < 20, WAIT_S)


def test_a_joint_commands_put_with_an_attachment_moves_the_joint(node, peer, types):
    move_joint_1_over_zenoh(node[0], peer, types)


@pytest.mark.parametrize(
    ("attachment", "payload", "why"),
    [
        (None, "good", "without an attachment"),
        (b"\x01\x02\x03", "good", "with a malformed attachment"),
        ("good", b"\x00\x01\x00\x00\xff\xff", "whose payload is not valid"),
    ],
    ids=["no_attachment", "malformed_attachment", "bad_cdr"],
)
def test_a_bad_put_is_dropped_counted_logged_once_and_nothing_moves(node, peer, types, attachment, payload, why):
    sim = node[0]
    call(peer, types, "/akd_node/enable", 9, bytes(16))
    before = sim.state(0)["position"]
    good = types.to_cdr(
        types.message(JOINT_STATE, name=["joint_1"], position=[before / COUNTS_PER_RAD + 0.5]), JOINT_STATE
    )
    payload = good if payload == "good" else payload
    for number in range(3):
        attached = Attachment(100 + number, time.time_ns(), bytes(16)).encode() if attachment == "good" else attachment
        if attached is None:
            peer.put(joint_commands_key(types), payload)
        else:
            peer.put(joint_commands_key(types), payload, attachment=attached)
    wait_for(
        "the drop logged",
        lambda: [line for line in output(node).splitlines() if "dropped" in line and why in line],
        WAIT_S,
    )
    time.sleep(0.3)
    # Had a command of them reached the drive, joint_1 would be well on its way to 0.5 rad (83 000 counts) away; it
    # may still settle by a few counts onto its last target.
    assert abs(sim.state(0)["position"] - before) < 50
    logged = [line for line in output(node).splitlines() if "dropped" in line and why in line]
    assert len(logged) == 1, logged


def test_diagnostics_over_zenoh_count_the_dropped_samples(node, peer, types):
    array = "diagnostic_msgs/msg/DiagnosticArray"
    key = data_key_expr(DOMAIN, "/diagnostics", dds_type_name(array), types.rihs01(array))
    seen: list = []
    subscriber = peer.declare_subscriber(key, lambda s: seen.append(types.from_cdr(s.payload.to_bytes(), array)))
    try:

        def dropped():
            for message in list(seen):
                for status in message.status:
                    values = {v.key: v.value for v in status.values}
                    if status.name == "akd_node: bus" and "zenoh_dropped" in values:
                        return int(values["zenoh_dropped"])
            return None

        # The three bad-put tests dropped three samples each.
        assert wait_for("a bus status with zenoh_dropped", dropped, WAIT_S) >= 9
    finally:
        subscriber.undeclare()


BOTH_DOMAIN = 35
"""The ROS_DOMAIN_ID of the `transport: both` run (DDS and the Zenoh keys alike); test_node_joints has 20-29."""


def test_transport_both_delivers_the_same_joint_states_to_rclpy_and_to_zenoh(router, peer, types, tmp_path):
    from sensor_msgs.msg import JointState

    from support.netns import free_udp_port
    from support.ros import NodeProcess, Participant, ros_environment

    key = data_key_expr(BOTH_DOMAIN, "/joint_states", dds_type_name(JOINT_STATE), types.rihs01(JOINT_STATE))
    over_zenoh: list = []
    subscriber = peer.declare_subscriber(
        key, lambda s: over_zenoh.append(types.from_cdr(s.payload.to_bytes(), JOINT_STATE))
    )
    sim = Sim(free_udp_port(), count=len(JOINTS))
    path = tmp_path / "akd_node.yaml"
    path.write_text(PARAMS.format(endpoint=router, port=sim.port).replace("transport: zenoh", "transport: both"))
    with ros_environment(range(BOTH_DOMAIN, BOTH_DOMAIN + 1)):
        node = NodeProcess(path, BOTH_DOMAIN)
        client = Participant(BOTH_DOMAIN, "both_test")
        over_dds: list = []
        client.node.create_subscription(JointState, "/joint_states", over_dds.append, 100)
        try:
            client.spin_until(lambda: len(over_dds) >= 20 and len(over_zenoh) >= 20, "joint_states on both")
        finally:
            client.close()
            stop(node.process)
            sim.stop()
            subscriber.undeclare()
            print("akd_node output:\n" + node.output())
    stamps = {(m.header.stamp.sec, m.header.stamp.nanosec): list(m.position) for m in over_dds}
    common = [m for m in over_zenoh if (m.header.stamp.sec, m.header.stamp.nanosec) in stamps]
    assert len(common) >= 10, (len(over_dds), len(over_zenoh))
    for m in common:
        assert list(m.name) == JOINTS and list(m.position) == stamps[m.header.stamp.sec, m.header.stamp.nanosec]


def test_transport_both_answers_services_and_takes_commands_over_zenoh(router, peer, types, tmp_path):
    """What arrives by Zenoh on a node of transport both is read into rclpy's classes and handed to the same callbacks
    as over rclpy: a service's request and its response, a command."""
    from support.netns import free_udp_port
    from support.ros import NodeProcess, ros_environment

    sim = Sim(free_udp_port(), count=len(JOINTS))
    path = tmp_path / "akd_node.yaml"
    path.write_text(PARAMS.format(endpoint=router, port=sim.port).replace("transport: zenoh", "transport: both"))
    with ros_environment(range(BOTH_DOMAIN, BOTH_DOMAIN + 1)):
        node = NodeProcess(path, BOTH_DOMAIN)
        try:
            wait_for(
                "the node active",
                lambda: "active: publishing" in node.output() or node.process.poll() is not None,
                WAIT_S,
            )
            assert node.process.poll() is None, node.output()
            move_joint_1_over_zenoh(sim, peer, types, BOTH_DOMAIN)
        finally:
            stop(node.process)
            sim.stop()
            print("akd_node output:\n" + node.output())


def test_without_a_router_the_node_warns_naming_it_runs_on_and_records_a_bag_rosbags_reads(tmp_path):
    from rosbags.highlevel import AnyReader

    from support.zenoh import free_tcp_port

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    path = tmp_path / "akd_node.yaml"
    path.write_text(
        "akd_node:\n  ros__parameters:\n    transport: zenoh\n"
        f'    zenoh.connect: ["{endpoint}"]\n    link: sim:2\n    joints: [a, b]\n    cycle_time: 0.002\n'
        f"    record.enabled: true\n    record.folder: {tmp_path / 'bags'}\n"
    )
    node = NodeProcess(path, without_ros=True)
    process, log = node.process, node.log
    try:
        wait_for("the node active", lambda: "active: publishing" in "".join(log) or process.poll() is not None, WAIT_S)
        time.sleep(1.0)
    finally:
        stop(process)
    text = "".join(log)
    assert process.returncode == 0, text
    assert f"no Zenoh router reachable at {endpoint}" in text and "keeps running" in text, text
    (bag,) = (tmp_path / "bags").iterdir()
    with AnyReader([bag]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        joints = {
            reader.deserialize(raw, c.msgtype).joint for c, _, raw in reader.messages() if c.topic.endswith("/cycle")
        }
    assert counts["/joint_states"] > 10 and counts["/akd_node/cycle"] > 100, counts
    assert joints == {"a", "b"}


def test_transport_both_without_rclpy_is_one_line_naming_the_way_out(tmp_path):
    path = tmp_path / "akd_node.yaml"
    path.write_text("akd_node:\n  ros__parameters:\n    transport: both\n    link: sim\n")
    argv, env = node_command(path, without_ros=True)
    done = subprocess.run(
        argv,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert "parameter transport 'both' needs rclpy" in done.stderr and "use transport zenoh" in done.stderr


def test_drive_io_and_set_outputs_over_zenoh(node, peer, types):
    drive_io, set_outputs = "akd_ros/msg/DriveIO", "akd_ros/srv/SetOutputs"
    key = data_key_expr(DOMAIN, "/akd_node/joint_1/io", dds_type_name(drive_io), types.rihs01(drive_io))
    seen: list = []
    subscriber = peer.declare_subscriber(key, lambda s: seen.append(types.from_cdr(s.payload.to_bytes(), drive_io)))
    try:
        wait_for("~/joint_1/io over Zenoh", lambda: seen, WAIT_S)
    finally:
        subscriber.undeclare()
    message = seen[-1]
    # The default mapping carries the digital inputs alone.
    assert (message.joint, message.digital_inputs_mapped, message.digital_outputs_mapped) == ("joint_1", True, False)
    assert len(message.inputs) == 7 and len(message.outputs) == 0
    service = data_key_expr(DOMAIN, "/akd_node/set_outputs", dds_type_name(set_outputs), types.rihs01(set_outputs))
    request = types.message(f"{set_outputs}_Request", joint="joint_2", outputs=["1"], values=[True])
    payload = types.to_cdr(request, f"{set_outputs}_Request")
    attachment = Attachment(1, time.time_ns(), bytes(range(48, 64))).encode()
    replies = list(peer.get(service, payload=payload, attachment=attachment, timeout=WAIT_S))
    assert len(replies) == 1 and replies[0].ok is not None, replies
    response = types.from_cdr(replies[0].ok.payload.to_bytes(), f"{set_outputs}_Response")
    assert not response.success
    assert response.message == (
        "outputs not set: outputs refused: the mapping of joint_2 carries no digital outputs (0x60FE:01); mappings "
        "that do with mode cyclic_synchronous_position: io, 0x1725/0x1B20"
    )
