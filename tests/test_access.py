"""akd_node over Zenoh with the authority and configurations `akd-access init` makes: real Zenoh sessions over
mutual TLS, each with a role's configuration, against the node on a virtual AKD.

The node runs without ROS (`transport: zenoh`, its `zenoh.config` the node.json5 written), listening on a loopback
port the test picks; the clients are this process's sessions opened from observer.json5, operator.json5 and
configurer.json5, plus one with a certificate of another authority and one with none. What each may do is judged at
the drive: akd-sim's state of the AKD.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh

from akd_ros.zenoh.types import Types
from akd_ros.zenoh.wire import Attachment, data_key_expr, dds_type_name
from support.netns import free_udp_port
from support.ros import COUNTS_PER_RAD, NodeProcess, Sim, stop
from support.waiting import wait_for
from support.zenoh import WAIT_S, free_tcp_port

AKD_ACCESS = [str(Path(sys.executable).with_name("akd-access"))]
"""akd-access, as its console script runs it."""
DOMAIN = 0
JOINT_STATE = "sensor_msgs/msg/JointState"
FLOAT64 = "std_msgs/msg/Float64"
TRIGGER = "std_srvs/srv/Trigger"
SDO_WRITE = "akd_ros/srv/SdoWrite"
QUIET_S = 2.0
"""How long a request that no rule allows is given to show an effect it must not have."""

PARAMS = """\
akd_node:
  ros__parameters:
    transport: zenoh
    zenoh.config: {config}
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    mode: cyclic_synchronous_position
    joint_states_rate: 50.0
"""


@pytest.fixture(scope="module")
def types():
    return Types()


@pytest.fixture(scope="module")
def authority(tmp_path_factory):
    directory = tmp_path_factory.mktemp("access")
    endpoint = f"tls/127.0.0.1:{free_tcp_port()}"
    done = subprocess.run(
        [*AKD_ACCESS, "init", str(directory), "--endpoint", endpoint], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    return directory, endpoint


@pytest.fixture(scope="module")
def node(authority, tmp_path_factory):
    directory, _ = authority
    sim = Sim(free_udp_port(), count=1)
    path = tmp_path_factory.mktemp("node") / "akd_node.yaml"
    path.write_text(PARAMS.format(config=directory / "node.json5", port=sim.port))
    node = NodeProcess(path, DOMAIN, without_ros=True)
    try:
        wait_for("the node active", lambda: "active:" in node.output() or node.process.poll() is not None, WAIT_S)
        assert node.process.poll() is None, node.output()
        yield sim, node
    finally:
        stop(node.process)
        sim.stop()
        print("akd_node output:\n" + node.output())


def session(config: zenoh.Config) -> zenoh.Session:
    return zenoh.open(config)


def client(authority, role: str) -> zenoh.Session:
    """A session of `role`'s configuration, once it is connected to the node."""
    directory, _ = authority
    opened = session(zenoh.Config.from_file(directory / f"{role}.json5"))
    wait_for(f"the {role} connected to the node", lambda: list(opened.info.peers_zid()), WAIT_S, 0.05)
    return opened


def joint_states(peer: zenoh.Session, types: Types) -> list[bytes]:
    received: list[bytes] = []
    key = data_key_expr(DOMAIN, "/joint_states", dds_type_name(JOINT_STATE), types.rihs01(JOINT_STATE))
    peer.declare_subscriber(key, lambda sample: received.append(sample.payload.to_bytes()))
    return received


def call(peer: zenoh.Session, types: Types, name: str, type_name: str, **fields) -> list:
    """The replies to one request of the service `name`."""
    key = data_key_expr(DOMAIN, name, dds_type_name(type_name), types.rihs01(type_name))
    request = types.to_cdr(types.message(f"{type_name}_Request", **fields), f"{type_name}_Request")
    attachment = Attachment(1, time.time_ns(), bytes(16)).encode()
    return [r for r in peer.get(key, payload=request, attachment=attachment, timeout=QUIET_S) if r.ok is not None]


def response(types: Types, replies: list, type_name: str):
    assert len(replies) == 1, replies
    return types.from_cdr(replies[0].ok.payload.to_bytes(), f"{type_name}_Response")


def put_position(peer: zenoh.Session, types: Types, position: float) -> None:
    key = data_key_expr(DOMAIN, "/akd_node/position_command", dds_type_name(FLOAT64), types.rihs01(FLOAT64))
    for number in range(1, 11):
        payload = types.to_cdr(types.message(FLOAT64, data=position), FLOAT64)
        peer.put(key, payload, attachment=Attachment(number, time.time_ns(), bytes(range(16))).encode())
        time.sleep(0.02)


@pytest.mark.parametrize("certificate", ["none", "another authority's"])
def test_a_client_without_a_certificate_of_the_authority_cannot_connect(node, authority, certificate, tmp_path):
    directory, _ = authority
    config = json.loads((directory / "observer.json5").read_text())
    tls = config["transport"]["link"]["tls"]
    if certificate == "none":
        del tls["connect_private_key"], tls["connect_certificate"]
    else:
        done = subprocess.run(
            [*AKD_ACCESS, "init", str(tmp_path), "--endpoint", "tls/127.0.0.1:1"], capture_output=True, timeout=60
        )
        assert done.returncode == 0
        tls["connect_private_key"], tls["connect_certificate"] = (
            str(tmp_path / "observer.key"),
            str(tmp_path / "observer.pem"),
        )
    stranger = session(zenoh.Config.from_json5(json.dumps(config)))
    try:
        time.sleep(QUIET_S)
        assert list(stranger.info.peers_zid()) == []
    finally:
        stranger.close()


def test_an_observer_sees_the_joint_but_its_commands_change_nothing(node, authority, types):
    sim, _ = node
    observer = client(authority, "observer")
    try:
        received = joint_states(observer, types)
        wait_for("joint_states at the observer", lambda: received, WAIT_S)
        start = sim.state(0)["position"]
        assert call(observer, types, "/akd_node/enable", TRIGGER) == []
        put_position(observer, types, start / COUNTS_PER_RAD + 0.05)
        assert call(observer, types, "/akd_node/sdo_write", SDO_WRITE, index=0x6060, subindex=0, data=[8]) == []
        time.sleep(QUIET_S)
        state = sim.state(0)
        assert state["state"] != "Operation enabled", state
        assert abs(state["position"] - start) < 50, (start, state)
    finally:
        observer.close()


def test_an_operator_enables_and_moves_the_joint_but_cannot_write_an_object(node, authority, types):
    sim, _ = node
    operator = client(authority, "operator")
    try:
        assert response(types, call(operator, types, "/akd_node/enable", TRIGGER), TRIGGER).success
        assert sim.state(0)["state"] == "Operation enabled"
        target = sim.state(0)["position"] / COUNTS_PER_RAD + 0.01
        put_position(operator, types, target)
        wait_for(
            "the joint at its target", lambda: abs(sim.state(0)["position"] / COUNTS_PER_RAD - target) < 1e-4, WAIT_S
        )
        assert call(operator, types, "/akd_node/sdo_write", SDO_WRITE, index=0x6060, subindex=0, data=[8]) == []
        assert response(types, call(operator, types, "/akd_node/disable", TRIGGER), TRIGGER).success
    finally:
        operator.close()


def test_a_configurer_writes_an_object(node, authority, types):
    configurer = client(authority, "configurer")
    try:
        # 0x6065 (following error window) is the AKD's to take at any state, and moves nothing.
        replies = call(configurer, types, "/akd_node/sdo_write", SDO_WRITE, index=0x6065, subindex=0, data=[0, 0, 1, 0])
        assert response(types, replies, SDO_WRITE).success
    finally:
        configurer.close()
