"""akd_node over Zenoh with the authority and configurations `akd-access init` makes: real Zenoh sessions over
mutual TLS, each with a role's configuration, against the node on a virtual AKD; and who the audit names over rclpy.

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
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import zenoh

from akd_ros.node.doors import BURST_GAP_S
from akd_ros.zenoh.entities import ZenohNode
from akd_ros.zenoh.types import Types
from support.netns import free_udp_port
from support.ros import COUNTS_PER_RAD, NodeProcess, Sim, node_on_sim, ros_environment, stop
from support.waiting import wait_for
from support.zenoh import WAIT_S, free_tcp_port, zenoh_router

AKD_ACCESS = [str(Path(sys.executable).with_name("akd-access"))]
"""akd-access, as its console script runs it."""
DOMAIN = 0
ROS_DOMAINS = range(231, 233)
"""The ROS_DOMAIN_IDs of this module's node over rclpy; other modules take other ranges."""
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
    doors: {doors}
"""
ACCESS_REQUEST = "akd_ros/msg/AccessRequest"


@pytest.fixture(scope="module")
def types():
    return Types()


def init(directory: Path, endpoint: str, *options: str) -> None:
    """`akd-access init directory --endpoint endpoint *options`, which must succeed."""
    done = subprocess.run(
        [*AKD_ACCESS, "init", str(directory), "--endpoint", endpoint, *options],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr


@contextmanager
def secure_node(directory: Path, folder: Path, doors: str) -> Iterator[tuple[Sim, NodeProcess]]:
    """A virtual AKD and akd_node on it with `directory`'s node.json5 and the roles `doors` open, once active."""
    sim = Sim(free_udp_port(), count=1)
    path = folder / "akd_node.yaml"
    path.write_text(PARAMS.format(config=directory / "node.json5", port=sim.port, doors=doors))
    node = NodeProcess(path, DOMAIN, without_ros=True)
    try:
        wait_for("the node active", lambda: "active:" in node.output() or node.process.poll() is not None, WAIT_S)
        assert node.process.poll() is None, node.output()
        yield sim, node
    finally:
        stop(node.process)
        sim.stop()
        print("akd_node output:\n" + node.output())


@pytest.fixture(scope="module")
def authority(tmp_path_factory):
    directory = tmp_path_factory.mktemp("access")
    endpoint = f"tls/127.0.0.1:{free_tcp_port()}"
    init(directory, endpoint)
    return directory, endpoint


@pytest.fixture(scope="module")
def node(authority, tmp_path_factory):
    with secure_node(authority[0], tmp_path_factory.mktemp("node"), "[observe, operate, configure]") as running:
        yield running


class Client:
    """A client of a role: a session of its configuration, connected to the node, with a ROS node on it as an
    rmw_zenoh client has (its liveliness tokens name it and its entities)."""

    def __init__(self, authority, role: str, types: Types) -> None:
        directory, _ = authority
        self.types = types
        self.session = zenoh.open(zenoh.Config.from_file(directory / f"{role}.json5"))
        info = self.session.info
        wait_for(f"the {role} connected", lambda: list(info.peers_zid()) or list(info.routers_zid()), WAIT_S, 0.05)
        self.node = ZenohNode(self.session, types, f"{role}_client", domain=DOMAIN)
        self.received: dict[str, list] = {}
        self._clients: dict[str, object] = {}

    def subscribe(self, topic: str, type_name: str) -> list:
        """What arrives on `topic` from now on, decoded."""
        received = self.received.setdefault(topic, [])
        decode = lambda cdr: self.types.from_cdr(cdr, type_name)  # noqa: E731
        self.node.subscription(topic, type_name, received.append, deserialize=decode)
        return received

    def call(self, name: str, type_name: str, **fields):
        """The response to one request of the service `name`, None when none came."""
        request = self.types.to_cdr(self.types.message(f"{type_name}_Request", **fields), f"{type_name}_Request")
        reply = self._client(name, type_name).call(request, QUIET_S)
        return None if reply is None else self.types.from_cdr(reply, f"{type_name}_Response")

    def _client(self, name: str, type_name: str):
        if name not in self._clients:
            self._clients[name] = self.node.client(name, type_name)
        return self._clients[name]

    def serving(self, name: str, type_name: str = TRIGGER) -> None:
        """Makes a client of the node's service `name` and waits until the service is known to this session, as an
        rmw_zenoh client waits for its service: a query goes only to the queryables a session knows of, and a
        session just connected learns of them over the next moments."""
        self._client(name, type_name)
        key = f"@ros2_lv/{DOMAIN}/*/*/*/SS/*/*/*/{name.replace('/', '%')}/**"
        wait_for(f"{name} served", lambda: list(self.session.liveliness().get(f"{key}", timeout=1)), WAIT_S, 0.1)

    def enable_recorded(self, sim: Sim) -> list:
        """Enables the joint (which must then be enabled at the drive); gives the ~/access records from before it on."""
        records = self.subscribe("/akd_node/access", ACCESS_REQUEST)
        self.serving("/akd_node/enable")
        time.sleep(0.5)
        assert self.call("/akd_node/enable", TRIGGER).success
        assert sim.state(0)["state"] == "Operation enabled"
        return records

    def put_position(self, position: float) -> None:
        publisher = self.node.publisher("/akd_node/position_command", FLOAT64)
        for _ in range(10):
            publisher.publish(self.types.to_cdr(self.types.message(FLOAT64, data=position), FLOAT64))
            time.sleep(0.02)

    def close(self) -> None:
        self.node.close()
        self.session.close()


@pytest.mark.parametrize("certificate", ["none", "another authority's"])
def test_a_client_without_a_certificate_of_the_authority_cannot_connect(node, authority, certificate, tmp_path):
    directory, _ = authority
    config = json.loads((directory / "observer.json5").read_text())
    tls = config["transport"]["link"]["tls"]
    if certificate == "none":
        del tls["connect_private_key"], tls["connect_certificate"]
    else:
        init(tmp_path, "tls/127.0.0.1:1")
        tls["connect_private_key"], tls["connect_certificate"] = (
            str(tmp_path / "observer.key"),
            str(tmp_path / "observer.pem"),
        )
    stranger = zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    try:
        time.sleep(QUIET_S)
        assert list(stranger.info.peers_zid()) == []
    finally:
        stranger.close()


def test_an_observer_sees_the_joint_but_its_commands_change_nothing_and_are_recorded_refused(node, authority, types):
    sim, process = node
    observer = Client(authority, "observer", types)
    try:
        # Declared before joint_states: once its samples arrive, the node knows of this subscriber too.
        records = observer.subscribe("/akd_node/access", ACCESS_REQUEST)
        received = observer.subscribe("/joint_states", JOINT_STATE)
        wait_for("joint_states at the observer", lambda: received, WAIT_S)
        start = sim.state(0)["position"]
        assert observer.call("/akd_node/enable", TRIGGER) is None
        observer.put_position(start / COUNTS_PER_RAD + 0.05)
        assert observer.call("/akd_node/sdo_write", SDO_WRITE, index=0x6060, subindex=0, data=[8]) is None
        time.sleep(QUIET_S)
        state = sim.state(0)
        assert state["state"] != "Operation enabled", state
        assert abs(state["position"] - start) < 50, (start, state)
        # Zenoh dropped all of it; the node recorded each of the observer's clients at a door it may not use.
        doors = {"/akd_node/enable", "/akd_node/position_command", "/akd_node/sdo_write"}
        wait_for("the refusals' records", lambda: doors <= {r.door for r in records}, WAIT_S)
        by_door = {r.door: r for r in records}
        assert set(by_door) == doors, records
        for record in by_door.values():
            assert not record.accepted, record
            assert "certificate observer" in record.caller and "node /observer_client" in record.caller, record
            assert record.outcome.startswith("certificate observer may not "), record
            assert "Zenoh's access control" in record.outcome, record
        assert (by_door["/akd_node/enable"].role, by_door["/akd_node/sdo_write"].role) == ("operate", "configure")
        assert by_door["/akd_node/position_command"].request == "made a publisher of /akd_node/position_command"
        assert "access: /akd_node/enable (operate) from zenoh: node /observer_client" in process.output()
    finally:
        observer.close()


def test_an_operator_enables_and_moves_the_joint_but_cannot_write_an_object(node, authority, types):
    sim, process = node
    operator = Client(authority, "operator", types)
    try:
        records = operator.enable_recorded(sim)
        target = sim.state(0)["position"] / COUNTS_PER_RAD + 0.01
        operator.put_position(target)
        wait_for(
            "the joint at its target", lambda: abs(sim.state(0)["position"] / COUNTS_PER_RAD - target) < 1e-4, WAIT_S
        )
        assert operator.call("/akd_node/sdo_write", SDO_WRITE, index=0x6060, subindex=0, data=[8]) is None
        assert operator.call("/akd_node/disable", TRIGGER).success
        # The audit trail: each request with who made it, the enable and disable each, the commands once a burst.
        wait_for("the disable's record", lambda: any(r.door == "/akd_node/disable" for r in records), WAIT_S)
        by_door = {r.door: r for r in records}
        doors = {"/akd_node/enable", "/akd_node/position_command", "/akd_node/disable", "/akd_node/sdo_write"}
        assert set(by_door) == doors, records
        refused = by_door["/akd_node/sdo_write"]
        assert (refused.role, refused.accepted, refused.request) == (
            "configure",
            False,
            "made a client of /akd_node/sdo_write",
        ), refused
        assert "certificate operator may not configure" in refused.outcome, refused
        enable = by_door["/akd_node/enable"]
        assert (enable.role, enable.accepted) == ("operate", True), enable
        assert "node /operator_client" in enable.caller and "certificate operator" in enable.caller, enable.caller
        assert by_door["/akd_node/position_command"].request.startswith("data="), records
        assert "certificate operator" in by_door["/akd_node/position_command"].caller, records
        assert "access: /akd_node/enable (operate) from zenoh: node /operator_client" in process.output()
    finally:
        operator.close()


def test_a_configurer_writes_an_object_and_a_refusal_is_recorded(node, authority, types):
    configurer = Client(authority, "configurer", types)
    try:
        records = configurer.subscribe("/akd_node/access", ACCESS_REQUEST)
        configurer.serving("/akd_node/sdo_write", SDO_WRITE)
        time.sleep(0.5)
        assert not configurer.call("/akd_node/sdo_write", SDO_WRITE, index=0x5FFF, subindex=0, data=[1]).success
        wait_for("the refusal's record", lambda: records, WAIT_S)
        assert (records[0].door, records[0].role, records[0].accepted) == ("/akd_node/sdo_write", "configure", False)
        assert "index=24575" in records[0].request and "certificate configurer" in records[0].caller, records[0]
        # 0x6065 (following error window) is the AKD's to take at any state, and moves nothing.
        assert configurer.call("/akd_node/sdo_write", SDO_WRITE, index=0x6065, subindex=0, data=[0, 0, 1, 0]).success
    finally:
        configurer.close()


def test_without_the_configure_role_sdo_write_does_not_exist(tmp_path, types):
    directory = tmp_path / "access"
    init(directory, f"tls/127.0.0.1:{free_tcp_port()}")
    authority = directory, None
    with secure_node(directory, tmp_path, "[observe, operate]") as (_, node):
        assert "doors open on zenoh: observe, operate; closed: sdo_write" in node.output(), node.output()
        configurer = Client(authority, "configurer", types)
        try:
            replies = configurer.session.liveliness().get(f"@ros2_lv/{DOMAIN}/**", timeout=5)
            tokens = [str(r.ok.key_expr) for r in replies if r.ok]
            assert any("%akd_node%enable" in t for t in tokens), tokens
            assert not any("sdo_write" in t for t in tokens), tokens
            assert configurer.call("/akd_node/sdo_write", SDO_WRITE, index=0x6065, subindex=0, data=[0]) is None
        finally:
            configurer.close()


def test_a_node_whose_endpoint_is_taken_says_so_in_one_line(node, authority, tmp_path):
    directory, endpoint = authority
    path = tmp_path / "akd_node.yaml"
    path.write_text(PARAMS.format(config=directory / "node.json5", port=free_udp_port(), doors="[observe, operate]"))
    second = NodeProcess(path, DOMAIN, without_ros=True)
    assert second.process.wait(timeout=WAIT_S) == 1, second.output()
    wait_for("the node's output", lambda: "error" in second.output(), WAIT_S)
    errors = [line for line in second.output().splitlines() if "error" in line.lower()]
    assert errors == [
        "akd_node: error: parameters zenoh.config/zenoh.connect: the Zenoh session does not open: Can not create a "
        f"new TLS listener on {endpoint[4:]}: {endpoint[4:]}: Address already in use (os error 98)"
    ], second.output()
    assert "Traceback" not in second.output()


def test_through_a_router_between_machines_the_roles_hold(tmp_path, types):
    directory = tmp_path / "access"
    router_port = free_tcp_port()
    init(directory, f"tls/127.0.0.1:{free_tcp_port()}", "--router", f"tls/127.0.0.1:{router_port}")
    connect = json.loads((directory / "operator.json5").read_text())["connect"]["endpoints"]
    assert connect == [f"tls/127.0.0.1:{router_port}"]
    authority = directory, None
    with (
        secure_node(directory, tmp_path, "[observe, operate]") as (sim, _),
        zenoh_router(router_port, directory / "router.json5"),
    ):
        observer = Client(authority, "observer", types)
        try:
            received = observer.subscribe("/joint_states", JOINT_STATE)
            wait_for("joint_states at the observer, through the router", lambda: received, WAIT_S)
            assert observer.call("/akd_node/enable", TRIGGER) is None
        finally:
            observer.close()
        assert sim.state(0)["state"] != "Operation enabled"
        operator = Client(authority, "operator", types)
        try:
            records = operator.enable_recorded(sim)
            assert operator.call("/akd_node/disable", TRIGGER).success
            wait_for("the enable's record", lambda: any(r.door == "/akd_node/enable" for r in records), WAIT_S)
            enable = next(r for r in records if r.door == "/akd_node/enable")
            # The node's only link is the router's: the client's node is named, its certificate is not.
            assert "node /operator_client" in enable.caller and "certificate" not in enable.caller, enable
        finally:
            operator.close()


def test_over_rclpy_the_record_names_the_clients_and_publishers_of_the_door_with_their_gids(tmp_path):
    from akd_ros.msg import AccessRequest

    params = PARAMS.replace("    transport: zenoh\n    zenoh.config: {config}\n", "").replace("{port}", "{{port}}")
    with (
        ros_environment(ROS_DOMAINS) as domain,
        node_on_sim(params.format(doors="[observe, operate]"), tmp_path, domain) as (_, _, ros),
    ):
        records = []
        access = ros.node.create_subscription(AccessRequest, "/akd_node/access", records.append, 100)
        ros.spin_until(lambda: access.get_publisher_count() > 0, "the node's ~/access")
        deadline = time.monotonic() + WAIT_S
        # Until the node's writer has matched this reader too (DDS matches each side on its own): a burst a round.
        while not {"/akd_node/enable", "/akd_node/position_command"} <= {r.door for r in records}:
            assert time.monotonic() < deadline, records
            ros.trigger("enable")
            ros.stream("position", [ros.position()] * 5)
            ros.spin_for(BURST_GAP_S + 0.1)
        by_door = {r.door: r for r in records}
        own = ros.node.get_publishers_info_by_topic("/akd_node/position_command")
        gid = bytes(next(i for i in own if i.node_name == "akd_node_test").endpoint_gid).hex()
        assert by_door["/akd_node/position_command"].caller == (
            f"dds: a publisher of the topic: /akd_node_test (gid {gid})"
        ), records
        # The client is gone once answered (Participant.call destroys it): its GID is named while it lives.
        enable = by_door["/akd_node/enable"].caller
        assert enable.startswith("dds: a client of the service: /akd_node_test (gid "), records
