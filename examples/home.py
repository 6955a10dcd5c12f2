"""Homes every joint of a running akd_node through its ~/home action (akd_ros/action/Home): each drive runs the homing
set up in it (on the AKD its HOME.* parameters), the node's cycle thread takes it into homing mode and back, and the
result says how each joint's homing ended. Homing needs the joints enabled: this enables them, and disables them
after. Under homing.required the node refuses to move a joint until it is homed.

    .venv/bin/akd_node --ros-args --params-file config/akd_sim_6axis.yaml    # in one terminal
    .venv/bin/python examples/home.py                                         # in another
"""

import sys

import rclpy
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.node import Node
from ros_helpers import enabled, init, run_goal, spin_until
from sensor_msgs.msg import JointState

from akd_ros.action import Home

NODE = sys.argv[1] if len(sys.argv) > 1 else "/akd_node"
STATUS = {GoalStatus.STATUS_SUCCEEDED: "SUCCEEDED", GoalStatus.STATUS_ABORTED: "ABORTED"}

init()
client = Node("akd_homing_client")
home = ActionClient(client, Home, f"{NODE}/home")
latest: list[JointState] = []
client.create_subscription(JointState, "/joint_states", latest.append, 10)
feedback = []


def on_feedback(message) -> None:
    """Feedback at 10 Hz: each joint's homing state (statusword bits 13, 12, 10), position and whether homed."""
    feedback.append(message.feedback)


spin_until(client, lambda: latest, "/joint_states")
with enabled(client, NODE):
    # No joints named: every joint of the node, homed together (or one by one: homing.sequence).
    status, result = run_goal(client, home, Home.Goal(joints=[]), f"{NODE}/home", on_feedback)
    positions = dict(zip(latest[-1].name, latest[-1].position, strict=True))
    for joint, outcome, homed, reason in zip(result.joints, result.outcome, result.homed, result.reason, strict=True):
        where = f"{'homed' if homed else 'not homed'}, at {positions[joint]:+.4f} rad"
        print(f"{joint}: {outcome}, {where}" + (f" ({reason})" if reason else ""))
    print(f"{NODE}/home: {STATUS.get(status, status)} after {len(feedback)} feedback messages: {result.message}")
client.destroy_node()
rclpy.shutdown()
sys.exit(0 if result.success else 1)
