"""An rclpy client of a running akd_node: enable every joint, move each by 0.1 rad through ~/joint_commands, read
/joint_states back, disable. Works with a node of one joint or of several, in a position mode. A command the node
refuses (a joint not homed under homing.required, a target past a limit) is not answered on the topic: the node logs
why, and this client prints that line and stops, the joints disabled.

    .venv/bin/akd_node --ros-args --params-file config/akd_sim.yaml      # in one terminal
    .venv/bin/python examples/node_client.py                              # in another
"""

import sys
import time

import rclpy
from rclpy.node import Node
from ros_helpers import NodeLog, enabled, init, spin_until
from sensor_msgs.msg import JointState

NODE = sys.argv[1] if len(sys.argv) > 1 else "/akd_node"

init()
client = Node("akd_client")
latest: list[JointState] = []
client.create_subscription(JointState, "/joint_states", latest.append, 10)
commands = client.create_publisher(JointState, f"{NODE}/joint_commands", 10)
log = NodeLog(client, NODE, "joint_commands")

spin_until(client, lambda: latest, "/joint_states")
with enabled(client, NODE):  # every joint in Operation enabled, each holding its actual position; disabled after
    start = latest[-1]
    spin_until(client, lambda: commands.get_subscription_count() > 0, f"subscriber of {NODE}/joint_commands")
    # A ramp of 0.1 rad over a second in steps of 1 mrad: the drive takes each step within one 1 ms cycle, and a few
    # commands delivered at once add up to one step, which must stay within max_velocity (6 mrad a cycle).
    for step in range(1, 101):
        targets = [p + 0.1 * step / 100 for p in start.position]
        commands.publish(JointState(name=list(start.name), position=targets))
        time.sleep(0.01)
    target = JointState(name=list(start.name), position=[p + 0.1 for p in start.position])

    def arrived() -> bool:
        return all(abs(p - t) < 1e-3 for p, t in zip(latest[-1].position, target.position, strict=True))

    def refused() -> bool:
        commands.publish(target)  # the target again while waiting: a refusal is logged, at most once a second
        return bool(log.lines)

    spin_until(client, lambda: arrived() or refused(), "joints at their targets")
    refusal = None if arrived() else log.lines[0]
    if refusal:
        print(f"{NODE}: {refusal}")
    else:
        for name, position in zip(latest[-1].name, latest[-1].position, strict=True):
            print(f"{name}: {position:+.4f} rad")
client.destroy_node()
rclpy.shutdown()
sys.exit(1 if refusal else 0)
