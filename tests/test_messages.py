"""akd_ros's own messages and services, built by setup.py (rosidl_build.py), used for real.

Real rclpy over rmw_fastrtps_cpp (the PyPI ROS wheels in .venv): a peer process, this file run
with .venv's python, publishes one sample of every message and serves every service; the test
subscribes and calls, and compares every field. CDR serialisation round-trips every type in
process. Each run takes its own ROS_DOMAIN_ID and keeps discovery on this host, so parallel runs
(and anything else on the network) do not cross. Every wait is bounded.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
from builtin_interfaces.msg import Time
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header

import akd_ros
from akd_ros.msg import CycleSample, DriveFault, DriveStatus, LatchEvent
from akd_ros.srv import ArmLatch, SdoRead, SdoWrite, SetMode
from support.ros import RMW, WAIT_S, Participant, ros_environment

REPO = Path(__file__).resolve().parents[1]
TOPIC_PREFIX = "/akd_messages_test/"
SERVICE_PREFIX = "/akd_messages_test/"
# ROS_DOMAIN_IDs of this module; other modules take other ranges.
DOMAINS = range(100, 201)
PEER_LIFETIME_S = 180.0
STAMP = Time(sec=1_764_000_000, nanosec=999_999_999)


def samples() -> dict[str, object]:
    """One message of each type, every field away from its default, limits where they bite."""
    header = Header(stamp=STAMP, frame_id="")
    return {
        "LatchEvent": LatchEvent(
            header=header,
            joint="axis_1",
            channel=2,
            edge=LatchEvent.EDGE_FALLING,
            position=-3.141592653589793,
            position_counts=-(2**31),
        ),
        "DriveFault": DriveFault(
            header=Header(stamp=STAMP, frame_id="drive"),
            joint="axis_1",
            source="emergency",
            code=0xFF00,
            text="F125: Fieldbus - synchronization lost",
            ds402_state="fault",
            al_state="safe_op",
            al_status_code=0x001A,
            action="quick_stop",
        ),
        "DriveStatus": DriveStatus(
            header=header,
            joint="axis_1",
            ds402_state="operation_enabled",
            statusword=0x1637,
            mode="cyclic_synchronous_position",
            mode_of_operation=8,
            following_error=-1.5e-6,
            cycles=2**64 - 1,
            overruns=3,
            lost_frames=2**40,
            wkc_errors=7,
            period_mean=0.001,
            period_max=0.00125,
            exchange_p99=4.2e-5,
        ),
        "CycleSample": CycleSample(
            stamp=STAMP,
            cycle=123_456_789_012,
            position=1e9,
            velocity=-62.83,
            torque=2.5,
            command=-1e-12,
            following_error=3.0e-7,
            position_counts=2**31 - 1,
            statusword=0xFFFF,
            mode_of_operation=-128,
            period_ns=2**32 - 1,
            exchange_ns=41_000,
            wkc=3,
        ),
    }


MESSAGE_TYPES = {
    "LatchEvent": LatchEvent,
    "DriveFault": DriveFault,
    "DriveStatus": DriveStatus,
    "CycleSample": CycleSample,
}
SERVICE_TYPES = {"SetMode": SetMode, "ArmLatch": ArmLatch, "SdoRead": SdoRead, "SdoWrite": SdoWrite}


def requests() -> dict[str, object]:
    """One request of each service, fields away from their defaults."""
    return {
        "SetMode": SetMode.Request(mode="cyclic_synchronous_velocity"),
        "ArmLatch": ArmLatch.Request(channel=2, edge=LatchEvent.EDGE_RISING, arm=True),
        "SdoRead": SdoRead.Request(index=0x6064, subindex=0xFF),
        "SdoWrite": SdoWrite.Request(index=0x60B8, subindex=1, data=[0x00, 0x7F, 0x80, 0xFF]),
    }


def answer(name: str, request) -> object:
    """The peer's response to request, made from every request field so a lost one shows."""
    response = SERVICE_TYPES[name].Response()
    if name == "SetMode":
        response.success, response.message = False, f"no mode {request.mode}"
    elif name == "ArmLatch":
        response.success = request.arm
        response.message = f"latch {request.channel} edge {request.edge} arm {request.arm}"
    elif name == "SdoRead":
        response.success, response.message = True, "read"
        response.data = [request.index & 0xFF, request.index >> 8, request.subindex, 0xAB]
    else:
        response.success = True
        response.message = f"{request.index:#06x}:{request.subindex} <- {bytes(request.data).hex()}"
    return response


def assert_same_fields(received, expected) -> None:
    """Every field of received equals expected's, named in the failure."""
    assert type(received) is type(expected)
    for field in type(expected).get_fields_and_field_types():
        got, want = getattr(received, field), getattr(expected, field)
        assert got == want, f"{type(expected).__name__}.{field}: got {got!r}, expected {want!r}"


def peer(lifetime_s: float) -> None:
    """The other process: publishes every sample every 50 ms and serves every service."""
    rclpy.init()
    node = rclpy.create_node("akd_messages_peer")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    publishers = {name: node.create_publisher(MESSAGE_TYPES[name], TOPIC_PREFIX + name, qos) for name in MESSAGE_TYPES}
    sample_messages = samples()

    def publish_all() -> None:
        for name, publisher in publishers.items():
            publisher.publish(sample_messages[name])

    def server(name: str):
        def callback(request, response):
            return answer(name, request)

        return callback

    node.create_timer(0.05, publish_all)
    for name, kind in SERVICE_TYPES.items():
        node.create_service(kind, SERVICE_PREFIX + name, server(name))
    deadline = time.monotonic() + lifetime_s
    while rclpy.ok() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    node.destroy_node()
    rclpy.shutdown()


@pytest.fixture(scope="module")
def ros_domain():
    """A ROS_DOMAIN_ID of this run's own, discovery on localhost, Fast DDS; set for the module."""
    with ros_environment(DOMAINS) as domain:
        yield domain


@pytest.fixture(scope="module")
def peer_process(ros_domain):
    """The peer (this file with .venv's python), running for the module's tests."""
    process = subprocess.Popen(
        [sys.executable, str(Path(__file__).resolve()), "peer"],
        env=dict(os.environ),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    yield process
    process.terminate()
    try:
        output, _ = process.communicate(timeout=WAIT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        output, _ = process.communicate()
    print(f"peer output:\n{output}")


@pytest.fixture
def ros(ros_domain):
    """This process's participant on the run's domain."""
    participant = Participant(ros_domain, "akd_messages_test")
    yield participant
    participant.close()


def test_the_middleware_is_fast_dds(ros):
    """The round trips below run over rmw_fastrtps_cpp, which takes Fast DDS type support."""
    assert rclpy.get_rmw_implementation_identifier() == RMW


@pytest.mark.parametrize("name", sorted(MESSAGE_TYPES))
def test_serialization_round_trips_every_message(name):
    expected = samples()[name]
    data = serialize_message(expected)
    assert isinstance(data, bytes) and data
    assert_same_fields(deserialize_message(data, MESSAGE_TYPES[name]), expected)


@pytest.mark.parametrize("name", sorted(SERVICE_TYPES))
def test_serialization_round_trips_every_request_and_response(name):
    request = requests()[name]
    response = answer(name, request)
    for message in (request, response):
        assert_same_fields(deserialize_message(serialize_message(message), type(message)), message)


def test_latch_edge_constants():
    assert (LatchEvent.EDGE_RISING, LatchEvent.EDGE_FALLING) == (1, 2)
    # The node's parts name the edges without the message classes, which a Zenoh transport builds otherwise.
    from akd_ros.node.publishing import EDGE_NAMES

    assert EDGE_NAMES == {LatchEvent.EDGE_RISING: "rising", LatchEvent.EDGE_FALLING: "falling"}


class MessageTypeSupport(ctypes.Structure):
    """rosidl_message_type_support_t (rosidl_runtime_c/message_type_support_struct.h)."""


MessageTypeSupport._fields_ = [
    ("typesupport_identifier", ctypes.c_char_p),
    ("data", ctypes.c_void_p),
    ("func", ctypes.CFUNCTYPE(ctypes.POINTER(MessageTypeSupport), ctypes.POINTER(MessageTypeSupport), ctypes.c_char_p)),
    ("get_type_hash_func", ctypes.c_void_p),
    ("get_type_description_func", ctypes.c_void_p),
    ("get_type_description_sources_func", ctypes.c_void_p),
]


class IntrospectionMember(ctypes.Structure):
    """rosidl_typesupport_introspection_c__MessageMember (Jazzy's layout)."""

    _fields_ = [
        ("name_", ctypes.c_char_p),
        ("type_id_", ctypes.c_uint8),
        ("string_upper_bound_", ctypes.c_size_t),
        ("members_", ctypes.c_void_p),
        ("is_key_", ctypes.c_bool),
        ("is_array_", ctypes.c_bool),
        ("array_size_", ctypes.c_size_t),
        ("is_upper_bound_", ctypes.c_bool),
        ("offset_", ctypes.c_uint32),
        ("default_value_", ctypes.c_void_p),
        *(
            (function, ctypes.c_void_p)
            for function in (
                "size_function",
                "get_const_function",
                "get_function",
                "fetch_function",
                "assign_function",
                "resize_function",
            )
        ),
    ]


class IntrospectionMembers(ctypes.Structure):
    """rosidl_typesupport_introspection_c__MessageMembers (Jazzy's layout)."""

    _fields_ = [
        ("message_namespace_", ctypes.c_char_p),
        ("message_name_", ctypes.c_char_p),
        ("member_count_", ctypes.c_uint32),
        ("size_of_", ctypes.c_size_t),
        ("has_any_key_member_", ctypes.c_bool),
        ("members_", ctypes.POINTER(IntrospectionMember)),
        ("init_function", ctypes.c_void_p),
        ("fini_function", ctypes.c_void_p),
    ]


@pytest.mark.parametrize("name", sorted(MESSAGE_TYPES))
def test_the_dispatch_finds_both_type_supports(name):
    # What an rmw does with the C type support rclpy hands it: ask the dispatch library for its
    # own kind by name. The introspection one describes the message field by field.
    package_dir = Path(akd_ros.__file__).parent
    dispatch = ctypes.CDLL(str(package_dir / "libakd_ros__rosidl_typesupport_c.so"))
    get_handle = getattr(dispatch, f"rosidl_typesupport_c__get_message_type_support_handle__akd_ros__msg__{name}")
    get_handle.restype = ctypes.POINTER(MessageTypeSupport)
    handle = get_handle()
    fast_dds = handle.contents.func(handle, b"rosidl_typesupport_fastrtps_c")
    assert fast_dds and fast_dds.contents.typesupport_identifier == b"rosidl_typesupport_fastrtps_c"
    introspection = handle.contents.func(handle, b"rosidl_typesupport_introspection_c")
    assert introspection, "no introspection type support"
    members = ctypes.cast(introspection.contents.data, ctypes.POINTER(IntrospectionMembers)).contents
    assert (members.message_namespace_, members.message_name_) == (b"akd_ros__msg", name.encode())
    assert [members.members_[i].name_.decode() for i in range(members.member_count_)] == list(
        MESSAGE_TYPES[name].get_fields_and_field_types()
    )


def test_the_build_stops_naming_the_generators_it_cannot_import():
    # setup.py's own command, run as pip or colcon would, with rosidl_generator_py unimportable.
    script = (
        "import runpy, sys; sys.modules['rosidl_generator_py'] = None; "
        "sys.argv = ['setup.py', 'generate_interfaces']; "
        "runpy.run_path('setup.py', run_name='__main__')"
    )
    build = subprocess.run(
        [sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=120, check=False
    )
    assert build.returncode != 0
    assert "rosidl_generator_py" in build.stderr and "scripts/setup.sh" in build.stderr, build.stderr


def test_without_any_generator_the_build_goes_on_without_the_messages_saying_so():
    # No ROS at all (the node over Zenoh alone): setup.py's command generates nothing, and no interface library or
    # package is built.
    script = (
        "import runpy, sys, rosidl_build; sys.modules.update(dict.fromkeys(rosidl_build.GENERATOR_MODULES)); "
        "assert rosidl_build.extensions() == [] and rosidl_build.interface_packages() == []; "
        "sys.argv = ['setup.py', 'generate_interfaces']; "
        "runpy.run_path('setup.py', run_name='__main__')"
    )
    build = subprocess.run(
        [sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=120, check=False
    )
    assert build.returncode == 0, build.stderr
    assert "akd_ros: building without its messages and services" in build.stderr, build.stderr
    assert "rosidl_adapter" in build.stderr and "rosidl_generator_py" in build.stderr, build.stderr


def test_messages_from_another_process_arrive_with_every_field(ros, peer_process):
    received: dict[str, object] = {}
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    for name, kind in MESSAGE_TYPES.items():
        ros.node.create_subscription(
            kind, TOPIC_PREFIX + name, lambda message, name=name: received.setdefault(name, message), qos
        )
    ros.spin_until(
        lambda: len(received) == len(MESSAGE_TYPES) or peer_process.poll() is not None,
        f"message of each of {sorted(MESSAGE_TYPES)}",
    )
    assert peer_process.poll() is None, "the peer process exited"
    expected = samples()
    for name in MESSAGE_TYPES:
        assert_same_fields(received[name], expected[name])


@pytest.mark.parametrize("name", sorted(SERVICE_TYPES))
def test_each_service_answers_from_another_process(ros, peer_process, name):
    client = ros.node.create_client(SERVICE_TYPES[name], SERVICE_PREFIX + name)
    ros.spin_until(lambda: client.service_is_ready() or peer_process.poll() is not None, f"{name} service")
    assert peer_process.poll() is None, "the peer process exited"
    request = requests()[name]
    future = client.call_async(request)
    ros.spin_until(future.done, f"{name} response")
    assert_same_fields(future.result(), answer(name, request))


if __name__ == "__main__":
    if sys.argv[1:] != ["peer"]:
        sys.exit(f"usage: {sys.argv[0]} peer  (the other process of tests/test_messages.py)")
    peer(PEER_LIFETIME_S)
