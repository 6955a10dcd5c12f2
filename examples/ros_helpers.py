"""What the ROS examples share: rclpy started so that Ctrl-C stops the example and not rclpy under it, spinning until
something arrived, calling one of akd_node's services or actions, its joints enabled for a block (and disabled after
it, however the block ends, Ctrl-C too), and what the node logs about a command it refused (a topic has no answer; the
node says why in its log, on /rosout)."""

import sys
import time
from contextlib import contextmanager

import rclpy
from rcl_interfaces.msg import Log
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

TIMEOUT_S = 30.0


def init() -> None:
    """rclpy.init without rclpy's own Ctrl-C handler, which would shut rclpy down under the example: Ctrl-C ends the
    wait it comes in, and the example can still disable the joints."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)


def spin_until(node: Node, done, what: str, timeout: float = TIMEOUT_S) -> None:
    """Spins `node` until done() is true; exits naming `what` after `timeout` seconds, or at Ctrl-C."""
    deadline = time.monotonic() + timeout
    try:
        while not done():
            if time.monotonic() > deadline:
                sys.exit(f"{node.get_name()}: no {what} within {timeout} s: is akd_node running?")
            rclpy.spin_once(node, timeout_sec=0.05)
    except KeyboardInterrupt:
        sys.exit(f"{node.get_name()}: interrupted while waiting for {what}")


def call(node: Node, service: str, kind=Trigger, request=None):
    """Calls `service` of type `kind` (Trigger by default) with `request` (an empty one by default); its response."""
    client = node.create_client(kind, service)
    spin_until(node, client.service_is_ready, f"service {service}")
    future = client.call_async(request if request is not None else kind.Request())
    spin_until(node, future.done, f"answer of {service}")
    node.destroy_client(client)
    return future.result()


def trigger(node: Node, service: str) -> str:
    """Calls Trigger service `service` (~/enable, ~/disable ...) and gives its message; exits with it when refused."""
    response = call(node, service)
    if not response.success:
        sys.exit(f"{node.get_name()}: {service}: {response.message}")
    return response.message


@contextmanager
def enabled(node: Node, akd_node: str):
    """Every joint of `akd_node` enabled for the block (~/enable, its message printed), and disabled after it
    (~/disable), also when the block exits early: nothing is left with its power stage on."""
    print("enable:", trigger(node, f"{akd_node}/enable"))
    try:
        yield
    finally:
        print("disable:", trigger(node, f"{akd_node}/disable"))


def run_goal(node: Node, action: ActionClient, goal, what: str, on_feedback=None, cancel_after: float | None = None):
    """Sends `goal` to `action`, waits for its end (cancelling it `cancel_after` seconds after it was accepted, where
    given) and gives (status, result). Exits when the server rejects the goal."""
    spin_until(node, action.server_is_ready, f"action server {what}")
    sent = action.send_goal_async(goal, feedback_callback=on_feedback)
    spin_until(node, sent.done, f"answer of {what}")
    handle = sent.result()
    if not handle.accepted:
        sys.exit(f"{node.get_name()}: {what}: goal rejected")
    ended = handle.get_result_async()
    if cancel_after is not None:
        accepted = time.monotonic()
        spin_until(node, lambda: ended.done() or time.monotonic() > accepted + cancel_after, f"end of {what}")
        if not ended.done():
            canceling = handle.cancel_goal_async()
            spin_until(node, canceling.done, f"answer to the cancel of {what}")
    spin_until(node, ended.done, f"end of {what}")
    return ended.result().status, ended.result().result


class NodeLog:
    """The warnings and errors `akd_node` (its fully qualified name) logs from now on about `about` (a word of the
    line: the topic, say), read from /rosout."""

    def __init__(self, node: Node, akd_node: str, about: str):
        self.lines: list[str] = []
        self._name, self._about = akd_node.strip("/").replace("/", "."), about
        self._since = node.get_clock().now().nanoseconds
        # Transient local, as /rosout is published: a line logged before the subscription matched is still had.
        qos = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(Log, "/rosout", self._on_log, qos)

    def _on_log(self, log: Log) -> None:
        logged = log.stamp.sec * 1_000_000_000 + log.stamp.nanosec
        if log.name == self._name and log.level >= Log.WARN and logged >= self._since and self._about in log.msg:
            self.lines.append(log.msg)
