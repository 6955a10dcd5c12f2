"""What the two ROS examples (node_client.py, joint_trajectory.py) share: spinning until something arrived, and
calling one of akd_node's Trigger services (~/enable, ~/disable ...)."""

import sys
import time

import rclpy
from rclpy.node import Node
from std_srvs.srv import Trigger

TIMEOUT_S = 30.0


def spin_until(node: Node, done, what: str) -> None:
    """Spins `node` until done() is true; exits naming `what` after TIMEOUT_S."""
    deadline = time.monotonic() + TIMEOUT_S
    while not done():
        if time.monotonic() > deadline:
            sys.exit(f"{node.get_name()}: no {what} within {TIMEOUT_S} s: is akd_node running?")
        rclpy.spin_once(node, timeout_sec=0.05)


def call(node: Node, service: str) -> str:
    """Calls Trigger service `service` and gives its message; exits with it when the node refused."""
    trigger = node.create_client(Trigger, service)
    spin_until(node, trigger.service_is_ready, f"service {service}")
    future = trigger.call_async(Trigger.Request())
    spin_until(node, future.done, f"answer of {service}")
    if not future.result().success:
        sys.exit(f"{node.get_name()}: {service}: {future.result().message}")
    return future.result().message
