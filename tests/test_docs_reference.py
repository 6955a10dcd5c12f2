"""The documentation's generated reference against a running node: what the reference lists (the parameter schema,
the topics and services the node's parts declare, `docs/_ext/akd_reference.py`) is what an `akd_node` process on
the virtual AKD has, through rclpy's graph and its list_parameters service, with one joint and with two; and the
README's node at a glance names every topic and service the node has and none it lacks.

What every rclpy lifecycle node has on top (its lifecycle and parameter services, /rosout, /parameter_events,
~/transition_event) is taken from a bare LifecycleNode made here, not written down.
"""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

import pytest
from rcl_interfaces.srv import ListParameters
from rclpy.action import get_action_server_names_and_types_by_node
from rclpy.lifecycle import LifecycleNode

from akd_ros import params
from akd_ros.node.interface import ACTION, PUBLISHER, SERVICE, SUBSCRIPTION, declared
from support.params_files import params_file
from support.ros import WAIT_S, NodeProcess, Participant, ros_environment, stop

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import akd_reference  # noqa: E402  (docs/_ext is the docs build's, put on the path above)

DOMAINS = range(40, 45)
NODE = "akd_node"
BARE = "akd_bare_lifecycle"
TRIGGER = "std_srvs/srv/Trigger"
# One joint, and two: the node shapes the reference lists (its topics and services under ~/ or ~/<joint>/).
FILES = {
    "one joint": "link: sim?missed=lost",
    "two joints": f"link: sim:2?missed=lost\njoints: [{', '.join(akd_reference.EXAMPLE_JOINTS)}]",
}


def graph_of(participant: Participant, name: str) -> dict[str, set[tuple[str, str]]]:
    """The publishers, subscriptions and services of node `name` (namespace /) as the graph has them: (name, type)."""
    node = participant.node
    return {
        PUBLISHER: {(t, types[0]) for t, types in node.get_publisher_names_and_types_by_node(name, "/")},
        SUBSCRIPTION: {(t, types[0]) for t, types in node.get_subscriber_names_and_types_by_node(name, "/")},
        SERVICE: {(s, types[0]) for s, types in node.get_service_names_and_types_by_node(name, "/")},
    }


def as_akd_node(entries: set[tuple[str, str]]) -> set[tuple[str, str]]:
    """The bare node's names as they would be on akd_node."""
    return {(n.replace(f"/{BARE}/", f"/{NODE}/"), t) for n, t in entries}


def parameter_names(participant: Participant, name: str) -> set[str]:
    client = participant.node.create_client(ListParameters, f"/{name}/list_parameters")
    participant.spin_until(client.service_is_ready, f"/{name}/list_parameters")
    future = client.call_async(ListParameters.Request())
    participant.spin_until(future.done, f"the parameters of {name}")
    participant.node.destroy_client(client)
    return set(future.result().result.names)


@pytest.fixture(scope="module")
def client():
    with ros_environment(DOMAINS) as domain:
        participant = Participant(domain, "akd_docs_reference")
        bare = LifecycleNode(BARE, context=participant.context)
        participant.executor.add_node(bare)
        try:
            yield participant
        finally:
            participant.executor.remove_node(bare)
            bare.destroy_node()
            participant.close()


@pytest.mark.parametrize("shape", FILES)
def test_the_reference_lists_what_a_running_node_has(client, shape, tmp_path):
    settings = params.settings(params.read_parameters_file(str(params_file(tmp_path, FILES[shape]))))
    expected = {kind: set() for kind in (PUBLISHER, SUBSCRIPTION, SERVICE, ACTION)}
    for endpoint in declared(settings):
        expected[endpoint.kind].add((endpoint.name, endpoint.type_name))
    node = NodeProcess(params_file(tmp_path, FILES[shape]), client.context.get_domain_id())
    try:
        enable = "/akd_node/enable"
        deadline = time.monotonic() + WAIT_S
        while NODE not in client.node.get_node_names() or (enable, TRIGGER) not in graph_of(client, NODE)[SERVICE]:
            assert node.process.poll() is None, f"akd_node exited:\n{node.output()}"
            assert time.monotonic() < deadline, f"no {enable} within {WAIT_S} s:\n{node.output()}"
            client.spin_for(0.1)
        client.spin_for(0.5)  # the rest of the node's entities, discovered with it
        graph, bare = graph_of(client, NODE), graph_of(client, BARE)
        for kind in (PUBLISHER, SUBSCRIPTION, SERVICE):
            # Lifecycle publishers are there from the start, active or not; an action's own topics and services
            # (NAME/_action/...) are the action's, compared below.
            own = {(name, kind_) for name, kind_ in graph[kind] - as_akd_node(bare[kind]) if "/_action/" not in name}
            assert own == expected[kind], kind
        actions = get_action_server_names_and_types_by_node(client.node, NODE, "/")
        assert {(name, kind) for name, kinds in actions for kind in kinds} == expected[ACTION]

        schema = {spec.name for spec in params.SCHEMA}
        defaults = {spec.name: spec.default for spec in params.SCHEMA}
        joints = {spec.name for spec in params.joint_specs([j.name for j in settings.joints], defaults)}
        own = parameter_names(client, NODE) - parameter_names(client, BARE)
        assert own == schema | (joints if settings.joint_namespaces else set())
    finally:
        stop(node.process)


def test_the_generated_pages_list_every_parameter_topic_service_and_message():
    pages = akd_reference.write_all()
    for spec in params.SCHEMA:
        assert f"| `{spec.name}` |" in pages["parameters.md"], spec.name
    found = akd_reference.doors()
    for name in found["topics"]:
        assert f"| `{name}` |" in pages["topics.md"], name
    for name in found["services"]:
        assert f"| `{name}` |" in pages["services.md"], name
    for name in found["actions"]:
        assert f"| `{name}` |" in pages["actions.md"], name
    for path in akd_reference.interface_files():
        assert f"## `akd_ros/{path.parent.name}/{path.stem}`" in pages["messages.md"], path
    for name, _ in akd_reference.console_scripts():
        assert f"## `{name}`" in pages["tools.md"], name


def test_the_readme_names_every_topic_and_service_the_node_has_and_no_other():
    glance = (ROOT / "README.md").read_text(encoding="utf-8").split("## The node at a glance")[1].split("\n## ")[0]
    named = set()
    for row in re.findall(r"^\| (`[^|]*) \|", glance, re.MULTILINE):
        names = re.findall(r"`([^`]+)`", row)
        # A row names its first door in full and may name siblings by their last part: `~/<joint>/x`, `y`.
        prefix = names[0].rsplit("/", 1)[0] + "/" if "/" in names[0] else ""
        named |= {names[0]} | {n if n.startswith(("/", "~")) else prefix + n for n in names[1:]}
    found = akd_reference.doors()
    assert named == set(found["topics"]) | set(found["services"]) | set(found["actions"])


def test_the_readme_groups_every_parameter_of_the_schema():
    glance = (ROOT / "README.md").read_text(encoding="utf-8").split("## The node at a glance")[1].split("\n## ")[0]
    groups = glance.split("| group | parameters |")[1]
    named = set(re.findall(r"`([a-z_.*]+)`", groups))
    wildcards = [name[:-1] for name in named if name.endswith(".*")]
    missing = [
        spec.name
        for spec in params.SCHEMA
        if spec.name not in named and not any(spec.name.startswith(prefix) for prefix in wildcards)
    ]
    assert missing == [], "parameters the README's groups do not name"
