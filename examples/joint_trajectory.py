"""A trajectory for every joint of a running akd_node through ~/joint_trajectory: the node's cycle thread
interpolates it (quintic here, since each point gives velocities and accelerations) and ~/trajectory_status says how
it went. The joints must be in interpolated_position or cyclic_synchronous_position.

    .venv/bin/akd_node --ros-args --params-file config/akd_sim_6axis.yaml    # in one terminal
    .venv/bin/python examples/joint_trajectory.py                             # in another
"""

import sys

import rclpy
from builtin_interfaces.msg import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile
from ros_helpers import enabled, init, spin_until
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from akd_ros.msg import TrajectoryStatus

NODE = sys.argv[1] if len(sys.argv) > 1 else "/akd_node"

init()
client = Node("akd_trajectory_client")
latest: list[JointState] = []
statuses: list[TrajectoryStatus] = []
client.create_subscription(JointState, "/joint_states", latest.append, 10)
client.create_subscription(TrajectoryStatus, f"{NODE}/trajectory_status", statuses.append, QoSProfile(depth=100))
trajectories = client.create_publisher(JointTrajectory, f"{NODE}/joint_trajectory", 10)


def point(positions: list[float], seconds: float) -> JointTrajectoryPoint:
    """A point at rest (velocity and acceleration 0) `seconds` after the start."""
    zeros = [0.0] * len(positions)
    return JointTrajectoryPoint(
        positions=positions,
        velocities=zeros,
        accelerations=zeros,
        time_from_start=Duration(sec=int(seconds), nanosec=int(seconds % 1 * 1e9)),
    )


spin_until(client, lambda: latest, "/joint_states")
with enabled(client, NODE):
    start = latest[-1]
    here = list(start.position)
    # Out by 0.3 rad and back, each joint; header.stamp zero: it starts when the node takes it.
    trajectory = JointTrajectory(
        joint_names=list(start.name),
        points=[point([p + 0.3 for p in here], 1.0), point(here, 2.0)],
    )
    spin_until(client, lambda: trajectories.get_subscription_count() > 0, f"subscriber of {NODE}/joint_trajectory")
    trajectories.publish(trajectory)
    spin_until(client, lambda: statuses and statuses[-1].state not in ("pending", "running"), "end of the trajectory")
    outcome = statuses[-1]
    print(f"trajectory {outcome.id} of {', '.join(outcome.joints)}: {outcome.state} {outcome.message}".rstrip())
client.destroy_node()
rclpy.shutdown()
sys.exit(0 if outcome.state == "done" else 1)
