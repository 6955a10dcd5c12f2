"""Two goals for every joint of a running akd_node through ~/follow_joint_trajectory
(control_msgs/action/FollowJointTrajectory), the action MoveIt drives an arm through: the first, out by 0.3 rad and
back, with a path tolerance, a goal tolerance and a goal time tolerance the node's cycle thread judges every cycle;
the second, slower, cancelled after a second, which brakes every joint to a standstill (at each joint's
trajectory.stop_deceleration) and ends CANCELED. The joints must be in interpolated_position or
cyclic_synchronous_position; this enables them, and disables them after.

    .venv/bin/akd_node --ros-args --params-file config/akd_sim_6axis.yaml    # in one terminal
    .venv/bin/python examples/follow_joint_trajectory.py                      # in another
"""

import sys

import rclpy
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from rclpy.action import ActionClient
from rclpy.node import Node
from ros_helpers import enabled, init, run_goal, spin_until
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance

NODE = sys.argv[1] if len(sys.argv) > 1 else "/akd_node"
STATUS = {
    GoalStatus.STATUS_SUCCEEDED: "SUCCEEDED",
    GoalStatus.STATUS_CANCELED: "CANCELED",
    GoalStatus.STATUS_ABORTED: "ABORTED",
}

init()
client = Node("akd_follow_joint_trajectory_client")
latest: list[JointState] = []
client.create_subscription(JointState, "/joint_states", latest.append, 10)
follow = ActionClient(client, FollowJointTrajectory, f"{NODE}/follow_joint_trajectory")
largest_error = [0.0]


def duration(seconds: float) -> Duration:
    return Duration(sec=int(seconds), nanosec=round(seconds % 1 * 1e9))


def goal(joints: list[str], points: list[tuple[list[float], float]]) -> FollowJointTrajectory.Goal:
    """A goal through `points` (positions, seconds from the start), each at rest, with the tolerances: each joint
    within 0.1 rad of the path, within 0.01 rad of the last point and slower than 0.05 rad/s there, at most 0.5 s
    after its time."""
    trajectory = JointTrajectory(
        joint_names=joints,
        points=[
            JointTrajectoryPoint(positions=p, velocities=[0.0] * len(p), time_from_start=duration(t)) for p, t in points
        ],
    )
    return FollowJointTrajectory.Goal(
        trajectory=trajectory,
        path_tolerance=[JointTolerance(name=j, position=0.1) for j in joints],
        goal_tolerance=[JointTolerance(name=j, position=0.01, velocity=0.05) for j in joints],
        goal_time_tolerance=duration(0.5),
    )


def on_feedback(message) -> None:
    """Feedback at follow_joint_trajectory.feedback_rate: desired, actual and their difference per joint."""
    largest_error[0] = max([largest_error[0], *(abs(e) for e in message.feedback.error.positions)])


spin_until(client, lambda: latest, "/joint_states")
with enabled(client, NODE):
    joints, here = list(latest[-1].name), list(latest[-1].position)
    out_and_back = goal(joints, [([p + 0.3 for p in here], 1.0), (here, 2.0)])
    status, result = run_goal(client, follow, out_and_back, "goal 1", on_feedback)
    followed = status == GoalStatus.STATUS_SUCCEEDED
    print(f"goal 1: {STATUS.get(status, status)}, error_code {result.error_code} {result.error_string}".rstrip())
    print(f"goal 1: largest position error in the feedback {largest_error[0]:.4f} rad")

    slow = goal(joints, [([p + 1.0 for p in here], 4.0)])
    status, result = run_goal(client, follow, slow, "goal 2", cancel_after=1.0)
    cancelled = status == GoalStatus.STATUS_CANCELED
    print(f"goal 2: {STATUS.get(status, status)} after 1 s, error_code {result.error_code} {result.error_string}")
    moved = [f"{name} {p - h:+.3f} rad" for name, p, h in zip(joints, latest[-1].position, here, strict=True)]
    print("goal 2: stopped at", ", ".join(moved))
client.destroy_node()
rclpy.shutdown()
sys.exit(0 if followed and cancelled else 1)
