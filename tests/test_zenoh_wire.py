"""akd_ros.zenoh.wire and .types against rmw_zenoh's format and rosidl's hashes: key expressions, RIHS01 hashes
(against rclpy's, from the compiled type supports, and rosidl's type description files), attachments, liveliness
tokens and their QoS field, GIDs."""

from __future__ import annotations

import json
import struct
import sys
from pathlib import Path

import pytest
import xxhash

from akd_ros.zenoh.types import PayloadError, Types, UnknownTypeError
from akd_ros.zenoh.wire import (
    ATTACHMENT_SIZE,
    DURATION_INFINITE,
    Attachment,
    Durability,
    Entity,
    EntityKind,
    History,
    NodeInfo,
    QoS,
    Reliability,
    TopicInfo,
    data_key_expr,
    dds_type_name,
    fully_qualified_name,
    gid_of,
    node_entity,
    ros_type_name,
)

JOINT_STATE_HASH = "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
OWN_MESSAGES = sorted(f"akd_ros/msg/{path.stem}" for path in (Path(__file__).parents[1] / "msg").glob("*.msg"))
OWN_SERVICES = sorted(f"akd_ros/srv/{path.stem}" for path in (Path(__file__).parents[1] / "srv").glob("*.srv"))
ZID = "54a72050aadeb4a0076d11ddce571586"


@pytest.fixture(scope="module")
def types() -> Types:
    return Types()


@pytest.fixture(scope="module")
def rclpy_hashes():
    """type name -> the hash rclpy reports for a publisher of it (rmw asks the compiled type support)."""
    import importlib

    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("hashes", context=context)

    def hash_of(typename: str) -> str:
        package, kind, name = typename.split("/")
        message = getattr(importlib.import_module(f"{package}.{kind}"), name)
        topic = f"/hash_{package}_{name}"
        node.create_publisher(message, topic, 1)
        return str(node.get_publishers_info_by_topic(topic)[0].topic_type_hash)

    yield hash_of
    node.destroy_node()
    rclpy.shutdown(context=context)


def test_data_key_expression_of_joint_states(types):
    key = data_key_expr(
        0, "/joint_states", dds_type_name("sensor_msgs/msg/JointState"), types.rihs01("sensor_msgs/msg/JointState")
    )
    assert key == f"0/joint_states/sensor_msgs::msg::dds_::JointState_/{JOINT_STATE_HASH}"
    assert data_key_expr(3, "/akd_node/joint_commands/", "x::msg::dds_::Y_", "RIHS01_0") == (
        "3/akd_node/joint_commands/x::msg::dds_::Y_/RIHS01_0"
    )


def test_type_names():
    assert dds_type_name("std_srvs/srv/Trigger") == "std_srvs::srv::dds_::Trigger_"
    assert ros_type_name("sensor_msgs::msg::dds_::JointState_") == "sensor_msgs/msg/JointState"
    for bad in ("JointState", "sensor_msgs/JointState", "sensor_msgs/action/X", "a//b"):
        with pytest.raises(ValueError, match="form <package>/msg/<Name>"):
            dds_type_name(bad)


@pytest.mark.parametrize(
    ("name", "expanded"),
    [
        ("joint_states", "/joint_states"),
        ("/joint_states", "/joint_states"),
        ("~/joint_commands", "/akd_node/joint_commands"),
        ("~", "/akd_node"),
        ("diagnostics/", "/diagnostics"),
    ],
)
def test_fully_qualified_names(name, expanded):
    assert fully_qualified_name(name, "/", "akd_node") == expanded
    assert fully_qualified_name(name, "/cell1", "akd_node") == (
        expanded if name.startswith("/") else "/cell1" + expanded
    )


def test_hashes_of_standard_messages_match_rclpy(types, rclpy_hashes):
    assert rclpy_hashes("sensor_msgs/msg/JointState") == JOINT_STATE_HASH == types.rihs01("sensor_msgs/msg/JointState")
    for typename in (
        "std_msgs/msg/Float64",
        "trajectory_msgs/msg/JointTrajectory",
        "diagnostic_msgs/msg/DiagnosticArray",
        "service_msgs/msg/ServiceEventInfo",
    ):
        assert types.rihs01(typename) == rclpy_hashes(typename), typename


@pytest.mark.parametrize("typename", OWN_MESSAGES)
def test_hashes_of_own_messages_match_rclpy(types, rclpy_hashes, typename):
    assert types.rihs01(typename) == rclpy_hashes(typename)


@pytest.mark.parametrize("typename", [*OWN_SERVICES, "std_srvs/srv/Trigger"])
def test_hashes_of_service_members_match_rclpy(types, rclpy_hashes, typename):
    """A service's request, response and event are messages rclpy can publish, so their hashes are checked
    against the compiled type supports; the service's own hash is the description over those three."""
    for member in ("Request", "Response", "Event"):
        assert types.rihs01(f"{typename}_{member}") == rclpy_hashes(f"{typename}_{member}"), member


def test_hash_of_a_service_matches_rosidls_type_description():
    """rosidl's generator writes every hash of a service's description into share/<pkg>/srv/<Name>.json."""
    share = Path(sys.prefix) / "share" / "std_srvs" / "srv" / "Trigger.json"
    if not share.is_file():
        pytest.skip(f"{share} not installed")
    expected = {entry["type_name"]: entry["hash_string"] for entry in json.loads(share.read_text())["type_hashes"]}
    assert "std_srvs/srv/Trigger" in expected
    types = Types()
    assert {typename: types.rihs01(typename) for typename in expected} == expected


def test_unknown_type_is_named(types):
    with pytest.raises(UnknownTypeError, match="'akd_ros/msg/Nope' is not known"):
        types.rihs01("akd_ros/msg/Nope")


def test_cdr_round_trip_with_defaults(types):
    message = types.message("sensor_msgs/msg/JointState", name=["shoulder"], position=[1.5])
    data = types.to_cdr(message, "sensor_msgs/msg/JointState")
    assert data[:4] == b"\x00\x01\x00\x00"  # CDR, little-endian
    back = types.from_cdr(data, "sensor_msgs/msg/JointState")
    assert back.name == ["shoulder"]
    assert list(back.position) == [1.5]
    assert back.header.frame_id == ""
    assert types.message("akd_ros/srv/SdoRead_Response").data.size == 0
    with pytest.raises(UnknownTypeError, match="has no field velocityy"):
        types.message("sensor_msgs/msg/JointState", velocityy=[])


@pytest.mark.parametrize("data", [b"", b"\x00\x01\x00", b"not cdr at all", b"\x00\x01\x00\x00\xff\xff\xff\x7f"])
def test_invalid_cdr_is_refused(types, data):
    with pytest.raises(PayloadError, match="not valid CDR of sensor_msgs/msg/JointState"):
        types.from_cdr(data, "sensor_msgs/msg/JointState")


def test_attachment_layout():
    gid = bytes(range(16))
    data = Attachment(1, 1_700_000_000_123_456_789, gid).encode()
    assert len(data) == ATTACHMENT_SIZE == 33
    assert data[:8] == (1).to_bytes(8, "little")
    assert data[8:16] == (1_700_000_000_123_456_789).to_bytes(8, "little")
    assert data[16] == 0x10
    assert data[17:] == gid
    assert Attachment.decode(data) == Attachment(1, 1_700_000_000_123_456_789, gid)


@pytest.mark.parametrize(
    ("data", "problem"),
    [
        (b"", "has 0 bytes, expected 33"),
        (bytes(32), "has 32 bytes, expected 33"),
        (bytes(34), "has 34 bytes, expected 33"),
        (struct.pack("<qqB16s", 1, 2, 0x0F, bytes(16)), "GID length byte is 0x0f, expected 0x10"),
        (struct.pack("<qqB16s", -1, 2, 0x10, bytes(16)), "sequence number -1 is negative"),
        (struct.pack("<qqB16s", 1, -2, 0x10, bytes(16)), "source timestamp -2 is negative"),
    ],
)
def test_attachment_decode_is_strict(data, problem):
    with pytest.raises(ValueError, match=problem):
        Attachment.decode(data)


def test_gid_is_xxh3_128_of_the_key_low_half_first():
    key = f"@ros2_lv/0/{ZID}/0/0/NN/%/%/akd_node"
    digest = xxhash.xxh3_128(key.encode()).digest()  # canonical: high 64 bits first, each big-endian
    assert gid_of(key) == digest[8:][::-1] + digest[:8][::-1]
    assert len(gid_of(key)) == 16


def test_node_token():
    entity = node_entity(ZID, 0, NodeInfo("akd_node"))
    assert entity.liveliness_key() == f"@ros2_lv/0/{ZID}/0/0/NN/%/%/akd_node"
    assert Entity.parse(entity.liveliness_key()) == entity
    namespaced = node_entity(ZID, 4, NodeInfo("akd_node", namespace="/cell1/robot", domain=7))
    assert namespaced.liveliness_key() == f"@ros2_lv/7/{ZID}/4/4/NN/%/%cell1%robot/akd_node"


def test_publisher_token_and_compact_qos(types):
    topic = TopicInfo("/joint_states", dds_type_name("sensor_msgs/msg/JointState"), JOINT_STATE_HASH, QoS())
    entity = Entity(ZID, 0, 3, EntityKind.PUBLISHER, NodeInfo("akd_node"), topic)
    key = entity.liveliness_key()
    assert key == (
        f"@ros2_lv/0/{ZID}/0/3/MP/%/%/akd_node/%joint_states/sensor_msgs::msg::dds_::JointState_/"
        f"{JOINT_STATE_HASH}/::,10:,:,:,,"
    )
    assert Entity.parse(key) == entity
    assert entity.gid == gid_of(key)
    assert entity.data_key_expr() == f"0/joint_states/sensor_msgs::msg::dds_::JointState_/{JOINT_STATE_HASH}"


@pytest.mark.parametrize(
    ("qos", "compact"),
    [
        (QoS(), "::,10:,:,:,,"),
        (QoS(depth=42), "::,:,:,:,,"),
        (QoS(reliability=Reliability.BEST_EFFORT, depth=1), "2::,1:,:,:,,"),
        (QoS(durability=Durability.TRANSIENT_LOCAL, depth=1), ":1:,1:,:,:,,"),
        (QoS(history=History.KEEP_ALL, depth=42), "::2,:,:,:,,"),
        (QoS(deadline=(1, 500), lifespan=(2, 0)), "::,10:1,500:2,0:,,"),
    ],
)
def test_qos_compact_form_round_trips(qos, compact):
    assert qos.to_keyexpr() == compact
    assert QoS.from_keyexpr(compact) == qos


def test_qos_adapted_as_rmw_zenoh_does():
    adapted = QoS(
        reliability=Reliability.SYSTEM_DEFAULT, durability=Durability.SYSTEM_DEFAULT, depth=0, deadline=(0, 0)
    ).adapted()
    assert adapted == QoS(depth=42)
    assert adapted.deadline == DURATION_INFINITE
    with pytest.raises(ValueError, match="reliability unknown is not supported"):
        QoS(reliability=Reliability.UNKNOWN).adapted()


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("::,10:,:,,", "has 5 ':'-separated parts, expected 6"),
        ("::10:,:,:,,", "history,depth part '10' has 1 ','-parts, expected 2"),
        ("7::,10:,:,:,,", "reliability 7 is not one of"),
        ("::,ten:,:,:,,", "depth 'ten' is not a non-negative integer"),
    ],
)
def test_qos_parse_names_the_bad_part(text, problem):
    with pytest.raises(ValueError, match=problem):
        QoS.from_keyexpr(text)


@pytest.mark.parametrize(
    ("key", "problem"),
    [
        (f"@ros2_lv/0/{ZID}/0/0/NN/%/%", "has 8 '/'-separated fields, expected 9 or 13"),
        (f"@other/0/{ZID}/0/0/NN/%/%/n", "is not under @ros2_lv"),
        (f"@ros2_lv/0/{ZID}/0/0/XX/%/%/n", "entity kind 'XX' is not one of NN, MP, MS, SS, SC"),
        (f"@ros2_lv/x/{ZID}/0/0/NN/%/%/n", "domain 'x' is not a non-negative integer"),
        (f"@ros2_lv/0/{ZID}/0/0/MP/%/%/n", "a publisher token has 9 fields"),
        (f"@ros2_lv/0/{ZID}/0/0/NN/%//n", "has an empty field 7"),
    ],
)
def test_token_parse_names_the_problem(key, problem):
    with pytest.raises(ValueError, match=problem):
        Entity.parse(key)


def test_entity_refuses_an_empty_field():
    with pytest.raises(ValueError, match="field 6 is empty"):
        node_entity(ZID, 0, NodeInfo("akd_node", enclave="")).liveliness_key()


NO_ROS_SCRIPT = """
import importlib.abc, sys

ROS = ("rclpy", "rcl", "rmw", "rosidl", "rpyutils", "ament", "builtin_interfaces", "std_srvs", "service_msgs")


class NoRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        top = name.split(".")[0]
        if top.startswith(ROS) or top.endswith("_msgs") or name in ("akd_ros.msg", "akd_ros.srv"):
            raise ImportError(f"{name} is a ROS module")


sys.meta_path.insert(0, NoRos())
from akd_ros.zenoh import entities, session, types, wire

store = types.Types()
message = store.message("sensor_msgs/msg/JointState", name=["j"], position=[1.0])
data = store.to_cdr(message, "sensor_msgs/msg/JointState")
print(store.rihs01("sensor_msgs/msg/JointState"), store.rihs01("akd_ros/srv/SetMode"), data.hex())
"""


def test_the_zenoh_side_needs_no_ros_module(types):
    """akd_ros.zenoh imports and works where every ROS module (rclpy, rosidl, message packages) is refused."""
    import subprocess

    result = subprocess.run(
        [sys.executable, "-c", NO_ROS_SCRIPT], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stderr
    data = types.to_cdr(
        types.message("sensor_msgs/msg/JointState", name=["j"], position=[1.0]), "sensor_msgs/msg/JointState"
    )
    assert result.stdout.split() == [JOINT_STATE_HASH, types.rihs01("akd_ros/srv/SetMode"), data.hex()]
