"""akd_ros.zenoh's session and entities on real Zenoh: a router in its own process on a loopback port, the node's
session, and an independent session that looks at the wire as an rmw_zenoh node would (exact key expressions,
attachments, liveliness tokens, service replies) and puts what a misbehaving peer might."""

from __future__ import annotations

import json
import threading
import time

import pytest
import zenoh

from akd_ros.zenoh.entities import ZenohNode, publisher_options
from akd_ros.zenoh.session import SessionConfigError, connect_endpoints, open_session, router_warning, session_config
from akd_ros.zenoh.types import Types
from akd_ros.zenoh.wire import (
    Attachment,
    Durability,
    Entity,
    EntityKind,
    History,
    QoS,
    Reliability,
    gid_of,
)
from support.waiting import wait_for
from support.zenoh import WAIT_S, free_tcp_port, liveliness_keys, zenoh_router, zenoh_session

JOINT_STATE = "sensor_msgs/msg/JointState"
TRIGGER = "std_srvs/srv/Trigger"


@pytest.fixture(scope="module")
def types() -> Types:
    return Types()


@pytest.fixture(scope="module")
def router():
    with zenoh_router() as endpoint:
        yield endpoint


@pytest.fixture
def sessions(router):
    """The node's session and an independent one, both through the router."""
    with zenoh_session(router) as node_session, zenoh_session(router) as peer:
        yield node_session, peer


@pytest.fixture
def logged():
    return []


@pytest.fixture
def node(sessions, types, logged):
    node = ZenohNode(sessions[0], types, "akd_node", log=logged.append)
    yield node
    node.close()


def _joint_state(types, position: float) -> bytes:
    return types.to_cdr(types.message(JOINT_STATE, name=["joint1"], position=[position]), JOINT_STATE)


def _at_least(count: int, keys: list[str]) -> list[str] | None:
    return keys if len(keys) >= count else None


def _entity_of(keys: list[str], kind: EntityKind, topic: str) -> tuple[str, Entity]:
    found = [(key, Entity.parse(key)) for key in keys]
    matching = [(key, entity) for key, entity in found if entity.kind is kind and entity.topic.name == topic]
    assert len(matching) == 1, f"{kind.name} tokens of {topic}: {matching} among {keys}"
    return matching[0]


def test_published_samples_carry_rmw_zenohs_key_and_attachments(sessions, node, types):
    _, peer = sessions
    publisher = node.publisher("joint_states", JOINT_STATE)
    key = f"0/joint_states/sensor_msgs::msg::dds_::JointState_/{types.rihs01(JOINT_STATE)}"
    assert publisher.key_expr == key
    samples = []
    published = []

    def publish(position: float) -> int:
        published.append(publisher.publish(_joint_state(types, position)))
        return published[-1]

    def sequence_number(sample: zenoh.Sample) -> int:
        return Attachment.decode(sample.attachment.to_bytes()).sequence_number

    subscriber = peer.declare_subscriber(key, samples.append)
    try:
        # A subscriber's declaration reaches the publisher's session through the router: publish until it does.
        wait_for("the first sample", lambda: publish(0.0) and samples, WAIT_S, 0.05)
        first = sequence_number(samples[0])
        for position in (1.0, 2.0, 3.0):
            publish(position)
        wait_for("the last sample", lambda: sequence_number(samples[-1]) == published[-1], WAIT_S, 0.01)
    finally:
        subscriber.undeclare()
    assert published == list(range(1, len(published) + 1))
    attachments = [Attachment.decode(sample.attachment.to_bytes()) for sample in samples]
    assert [a.sequence_number for a in attachments] == list(range(first, first + len(samples)))
    assert attachments[0].sequence_number >= 1
    stamps = [a.source_timestamp for a in attachments]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    assert abs(stamps[-1] - time.time_ns()) < 60e9
    keys = wait_for("the publisher's token", lambda: _at_least(2, liveliness_keys(peer)))
    publisher_key, _ = _entity_of(keys, EntityKind.PUBLISHER, "/joint_states")
    assert {a.gid for a in attachments} == {gid_of(publisher_key)} == {publisher.gid}
    assert {str(sample.key_expr) for sample in samples} == {key}
    assert list(types.from_cdr(samples[-1].payload.to_bytes(), JOINT_STATE).position) == [3.0]


def test_sequence_numbers_start_at_one_per_publisher(node, types):
    first = node.publisher("a_topic", JOINT_STATE)
    second = node.publisher("b_topic", JOINT_STATE)
    assert [first.publish(_joint_state(types, 0.0)) for _ in range(3)] == [1, 2, 3]
    assert second.publish(_joint_state(types, 0.0)) == 1
    assert first.gid != second.gid


def test_liveliness_tokens_list_the_node_and_its_entities(sessions, node, types):
    _, peer = sessions
    node.publisher("joint_states", JOINT_STATE, QoS(reliability=Reliability.BEST_EFFORT, depth=1))
    node.subscription("~/joint_commands", JOINT_STATE, lambda message: None)
    node.service("~/enable", TRIGGER, lambda request: b"")
    keys = wait_for("the node's four tokens", lambda: _at_least(4, liveliness_keys(peer)))
    entities = [Entity.parse(key) for key in keys]
    (node_token,) = [entity for entity in entities if entity.kind is EntityKind.NODE]
    assert node_token.node.name == "akd_node"
    assert node_token.node.namespace == "/"
    assert node_token.zid == str(sessions[0].zid())
    _, publisher = _entity_of(keys, EntityKind.PUBLISHER, "/joint_states")
    assert publisher.topic.dds_type == "sensor_msgs::msg::dds_::JointState_"
    assert publisher.topic.type_hash == types.rihs01(JOINT_STATE)
    assert publisher.topic.qos == QoS(reliability=Reliability.BEST_EFFORT, depth=1)
    _, subscription = _entity_of(keys, EntityKind.SUBSCRIPTION, "/akd_node/joint_commands")
    assert subscription.node == node_token.node
    _, service = _entity_of(keys, EntityKind.SERVICE, "/akd_node/enable")
    assert service.topic.dds_type == "std_srvs::srv::dds_::Trigger_"
    assert service.topic.type_hash == types.rihs01(TRIGGER)
    # One counter per session: the node is 0, its entities follow in the order declared.
    assert sorted(entity.entity_id for entity in entities) == [0, 1, 2, 3]
    assert {entity.node_id for entity in entities} == {node.node_id}


def test_service_reply_carries_the_requests_sequence_number_and_client_gid(sessions, node, types):
    _, peer = sessions
    requests = []

    def enable(request: object) -> bytes:
        requests.append(request)
        return types.to_cdr(
            types.message(f"{TRIGGER}_Response", success=True, message="enabled"), f"{TRIGGER}_Response"
        )

    service = node.service(
        "~/enable", TRIGGER, enable, deserialize_request=lambda data: types.from_cdr(data, f"{TRIGGER}_Request")
    )
    assert service.key_expr == f"0/akd_node/enable/std_srvs::srv::dds_::Trigger_/{types.rihs01(TRIGGER)}"
    client_gid = bytes(range(100, 116))
    request = types.to_cdr(types.message(f"{TRIGGER}_Request"), f"{TRIGGER}_Request")

    def call(sequence_number: int) -> list[zenoh.Reply]:
        attachment = Attachment(sequence_number, time.time_ns(), client_gid).encode()
        return list(peer.get(service.key_expr, payload=request, attachment=attachment, timeout=WAIT_S))

    replies = wait_for("a reply", lambda: call(41), WAIT_S, 0.1)
    sent = time.time_ns()
    replies = call(42)
    assert len(replies) == 1 and replies[0].ok is not None, replies
    reply = replies[0].ok
    assert str(reply.key_expr) == service.key_expr
    attachment = Attachment.decode(reply.attachment.to_bytes())
    assert attachment.sequence_number == 42
    assert attachment.gid == client_gid
    assert attachment.source_timestamp >= sent - 1_000_000_000
    response = types.from_cdr(reply.payload.to_bytes(), f"{TRIGGER}_Response")
    assert (response.success, response.message) == (True, "enabled")
    assert service.answered >= 2
    assert service.dropped.total == 0


def test_a_client_calls_with_rmw_zenohs_attachment_and_is_listed(sessions, node, types):
    _, peer = sessions
    client = node.client("/akd_node/enable", TRIGGER)
    assert client.key_expr == f"0/akd_node/enable/std_srvs::srv::dds_::Trigger_/{types.rihs01(TRIGGER)}"
    requests: list[Attachment] = []
    response = types.to_cdr(
        types.message(f"{TRIGGER}_Response", success=True, message="enabled"), f"{TRIGGER}_Response"
    )

    def serve(query: zenoh.Query) -> None:
        # As an rmw_zenoh service answers: the request's sequence number and the client's GID back.
        asked = Attachment.decode(query.attachment.to_bytes())
        requests.append(asked)
        query.reply(client.key_expr, response, attachment=Attachment(asked.sequence_number, 0, asked.gid).encode())

    queryable = peer.declare_queryable(client.key_expr, serve, complete=True)
    try:
        request = types.to_cdr(types.message(f"{TRIGGER}_Request"), f"{TRIGGER}_Request")
        replies = [wait_for("a reply", lambda: client.call(request, WAIT_S), WAIT_S, 0.1), client.call(request, WAIT_S)]
    finally:
        queryable.undeclare()
    assert [types.from_cdr(reply, f"{TRIGGER}_Response").message for reply in replies] == ["enabled", "enabled"]
    # Numbered from 1, one per call; calls made before the queryable was reached got no reply.
    numbers = [asked.sequence_number for asked in requests]
    assert len(numbers) >= 2 and numbers == list(range(numbers[-1] - len(numbers) + 1, numbers[-1] + 1))
    assert {asked.gid for asked in requests} == {client.gid}
    keys = wait_for("the client's token", lambda: _at_least(2, liveliness_keys(peer)))
    key, entity = _entity_of(keys, EntityKind.CLIENT, "/akd_node/enable")
    assert entity.node.name == "akd_node" and gid_of(key) == client.gid


def test_bad_requests_get_no_reply_and_are_counted(sessions, node, types, logged):
    _, peer = sessions
    service = node.service(
        "~/enable",
        TRIGGER,
        lambda request: b"\x00\x01\x00\x00\x01\x00\x00\x00\x01\x00\x00\x00\x00",
        deserialize_request=lambda data: types.from_cdr(data, f"{TRIGGER}_Request"),
    )
    good = Attachment(1, time.time_ns(), bytes(16)).encode()
    request = types.to_cdr(types.message(f"{TRIGGER}_Request"), f"{TRIGGER}_Request")
    wait_for(
        "the service",
        lambda: [r for r in peer.get(service.key_expr, payload=request, attachment=good, timeout=WAIT_S) if r.ok],
        WAIT_S,
        0.1,
    )
    for attachment, payload in ((None, request), (good[:-1], request), (good, b"junk")):
        replies = list(peer.get(service.key_expr, payload=payload, attachment=attachment, timeout=1.0))
        assert [reply.ok for reply in replies if reply.ok is not None] == []
    assert service.dropped.counts == {"no_attachment": 1, "bad_attachment": 1, "bad_payload": 1}
    # One line for each reason, the first time it happens.
    assert len([line for line in logged if "service /akd_node/enable" in line]) == 3


def test_bad_samples_are_dropped_counted_and_logged_once_for_each_reason(sessions, node, types, logged):
    _, peer = sessions
    received = []
    subscription = node.subscription(
        "~/joint_commands", JOINT_STATE, received.append, deserialize=lambda data: types.from_cdr(data, JOINT_STATE)
    )
    key = subscription.key_expr
    assert key == f"0/akd_node/joint_commands/sensor_msgs::msg::dds_::JointState_/{types.rihs01(JOINT_STATE)}"
    gid = bytes(range(16))
    publisher = peer.declare_publisher(key)
    sequence = iter(range(1, 1000))

    def put(position: float, attachment: bytes | None = b"valid") -> None:
        if attachment == b"valid":
            attachment = Attachment(next(sequence), time.time_ns(), gid).encode()
        publisher.put(_joint_state(types, position), attachment=attachment)

    # Warm-up commands (position 0) until the subscription's declaration has reached the peer.
    wait_for("the first command", lambda: put(0.0) or received, WAIT_S, 0.05)
    put(1.25, None)  # no attachment
    put(1.25, Attachment(next(sequence), time.time_ns(), gid).encode()[:32])
    put(1.25, b"\x01" * 33)  # GID length byte 0x01
    publisher.put(b"\x00\x01\x00\x00\x05", attachment=Attachment(next(sequence), time.time_ns(), gid).encode())
    put(2.5)
    positions = wait_for(
        "the good command after the bad ones",
        lambda: (seen := [list(message.position) for message in received]) and seen[-1] == [2.5] and seen,
        WAIT_S,
    )
    publisher.undeclare()
    assert subscription.dropped.counts == {"no_attachment": 1, "bad_attachment": 2, "bad_payload": 1}
    assert [position for position in positions if position != [0.0]] == [[2.5]]
    assert subscription.received == len(received)
    drops = [line for line in logged if "subscription /akd_node/joint_commands" in line]
    # One line for each reason the first time (the second malformed attachment is counted only).
    assert len(drops) == 3, logged
    assert "without an attachment" in drops[0] and "malformed attachment" in drops[1] and "payload" in drops[2]


def test_transient_local_history_reaches_a_late_subscription(router, types):
    """A latched topic (e.g. a drive's status) goes through zenoh-ext's advanced publisher with a cache of the
    history depth; a subscription declared afterwards, in another session, gets the cached samples."""
    latched = QoS(durability=Durability.TRANSIENT_LOCAL, depth=2)
    with zenoh_session(router) as first, zenoh_session(router) as second:
        publishing = ZenohNode(first, types, "akd_node")
        late = ZenohNode(second, types, "late")
        try:
            publisher = publishing.publisher("drive_status", JOINT_STATE, latched)
            for position in (1.0, 2.0, 3.0):
                publisher.publish(_joint_state(types, position))
            received = []
            late.subscription(
                "/drive_status",
                JOINT_STATE,
                received.append,
                latched,
                deserialize=lambda data: list(types.from_cdr(data, JOINT_STATE).position),
            )
            wait_for("the cached samples", lambda: len(received) >= 2, WAIT_S)
            time.sleep(0.2)
            assert received == [[2.0], [3.0]]
        finally:
            late.close()
            publishing.close()


def test_qos_maps_to_zenoh_options_as_rmw_zenoh_does():
    assert publisher_options(QoS()) == {
        "reliability": zenoh.Reliability.RELIABLE,
        "congestion_control": zenoh.CongestionControl.DROP,
    }
    assert publisher_options(QoS(history=History.KEEP_ALL))["congestion_control"] == zenoh.CongestionControl.BLOCK
    best_effort_all = publisher_options(QoS(reliability=Reliability.BEST_EFFORT, history=History.KEEP_ALL))
    assert best_effort_all == {
        "reliability": zenoh.Reliability.BEST_EFFORT,
        "congestion_control": zenoh.CongestionControl.DROP,
    }


def test_default_config_is_rmw_zenohs():
    config = session_config()
    assert json.loads(config.get_json("mode")) == "peer"
    assert connect_endpoints(config) == ["tcp/localhost:7447"]
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert connect_endpoints(session_config(connect=["tcp/10.0.0.2:7447", "tcp/10.0.0.3:7447"])) == [
        "tcp/10.0.0.2:7447",
        "tcp/10.0.0.3:7447",
    ]


def test_config_file_and_bad_overrides(tmp_path):
    path = tmp_path / "zenoh.json5"
    path.write_text('{ mode: "client", connect: { endpoints: ["tcp/127.0.0.1:7999"] } // a comment\n}')
    config = session_config(path)
    assert json.loads(config.get_json("mode")) == "client"
    assert connect_endpoints(config) == ["tcp/127.0.0.1:7999"]
    with pytest.raises(SessionConfigError, match="is not a file"):
        session_config(tmp_path / "missing.json5")
    (tmp_path / "bad.json5").write_text("{ mode: ")
    with pytest.raises(SessionConfigError, match="is not a Zenoh configuration"):
        session_config(tmp_path / "bad.json5")
    with pytest.raises(SessionConfigError, match="'localhost' is not of the form <protocol>/<address>"):
        session_config(connect=["localhost"])


def test_no_router_gives_a_warning_naming_the_address_and_the_session_keeps_running(types):
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    config = session_config(connect=[endpoint])
    session = open_session(config)
    try:
        warning = router_warning(session, config, timeout=0.5)
        assert warning is not None and endpoint in warning
        node = ZenohNode(session, types, "akd_node", log=lambda line: None)
        assert node.publisher("joint_states", JOINT_STATE).publish(_joint_state(types, 0.0)) == 1
        node.close()
    finally:
        session.close()


def test_router_found_gives_no_warning(router):
    config = session_config(connect=[router])
    session = open_session(config)
    try:
        assert router_warning(session, config, timeout=WAIT_S) is None
    finally:
        session.close()


def test_a_router_started_later_is_joined(types):
    """The node started before its router: once the router is up, its tokens reach others."""
    port = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    config = session_config(connect=[endpoint])
    session = open_session(config)
    try:
        node = ZenohNode(session, types, "early", log=lambda line: None)
        with zenoh_router(port), zenoh_session(endpoint) as peer:
            wait_for(
                "the early node's token",
                lambda: any(Entity.parse(key).node.name == "early" for key in liveliness_keys(peer)),
                WAIT_S,
                0.2,
            )
        node.close()
    finally:
        session.close()


def test_service_handler_runs_off_zenohs_threads(sessions, node, types):
    """A slow handler (a drive being enabled) does not hold up the node's subscriptions."""
    _, peer = sessions
    release = threading.Event()
    slow = node.service("~/slow", TRIGGER, lambda request: release.wait(WAIT_S) and b"")
    received = []
    subscription = node.subscription("~/joint_commands", JOINT_STATE, received.append)
    attachment = Attachment(1, time.time_ns(), bytes(16)).encode()
    peer.get(slow.key_expr, lambda reply: None, attachment=attachment, timeout=WAIT_S)
    publisher = peer.declare_publisher(subscription.key_expr)
    try:
        wait_for(
            "a sample while the handler waits",
            lambda: publisher.put(_joint_state(types, 0.0), attachment=attachment) or received,
            WAIT_S,
            0.05,
        )
    finally:
        release.set()
        publisher.undeclare()
