"""Sets a joint's digital outputs through ~/set_outputs (akd_ros/SetOutputs): by the name the parameters file gives
one (io.outputs) or by the AKD's number, written in the next cycle's process image; the joint's ~/<joint>/io
(akd_ros/DriveIO) shows them as sent. A request the node cannot carry out is refused whole, in one line, and nothing
is written. In config/akd_sim_6axis.yaml joint_6's output 1 is named gripper_open.

    .venv/bin/akd_node --ros-args --params-file config/akd_sim_6axis.yaml    # in one terminal
    .venv/bin/python examples/set_outputs.py                                  # in another
"""

import sys

import rclpy
from rclpy.node import Node
from ros_helpers import call, init, spin_until

from akd_ros.msg import DriveIO
from akd_ros.srv import SetOutputs

NODE = sys.argv[1] if len(sys.argv) > 1 else "/akd_node"
JOINT = sys.argv[2] if len(sys.argv) > 2 else "joint_6"

init()
client = Node("akd_outputs_client")
io: list[DriveIO] = []
client.create_subscription(DriveIO, f"{NODE}/{JOINT}/io", io.append, 10)


def set_outputs(outputs: list[str], values: list[bool]) -> SetOutputs.Response:
    request = SetOutputs.Request(joint=JOINT, outputs=outputs, values=values)
    response = call(client, f"{NODE}/set_outputs", SetOutputs, request)
    print(f"set {', '.join(f'{o}={v}' for o, v in zip(outputs, values, strict=True))}: {response.message}")
    return response


def shown() -> str:
    """The outputs as the joint's latest ~/io shows them."""
    latest = io[-1]
    named = [
        f"{n} ({k}) {'high' if v else 'low'}"
        for n, k, v in zip(latest.output_names, latest.output_numbers, latest.named_outputs, strict=True)
    ]
    levels = " ".join(f"{i}={'high' if v else 'low'}" for i, v in enumerate(latest.outputs, start=1))
    return f"{JOINT} io: outputs {levels}; {', '.join(named)}"


done = set_outputs(["gripper_open", "2"], [True, True])
spin_until(client, lambda: io and all(io[-1].outputs), f"{JOINT}'s io showing the outputs high")
print(shown())
refused = set_outputs(["valve"], [True])  # no output of joint_6 is named valve
back = set_outputs(["gripper_open", "2"], [False, False])
spin_until(client, lambda: io and not any(io[-1].outputs), f"{JOINT}'s io showing the outputs low")
print(shown())
client.destroy_node()
rclpy.shutdown()
sys.exit(0 if done.success and back.success and not refused.success else 1)
