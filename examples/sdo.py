"""Reads and writes one object of a joint's drive through ~/<joint>/sdo_read and ~/<joint>/sdo_write (akd_ros/SdoRead,
SdoWrite), by SDO beside the cycle: joint_2's following error window 0x6065 (in counts, past which the AKD faults
with F439), written smaller, read back and written back as it was; then an object the drive does not have, which the
drive refuses with an SDO abort code, named in the answer.

    .venv/bin/akd_node --ros-args --params-file config/akd_sim_6axis.yaml    # in one terminal
    .venv/bin/python examples/sdo.py                                          # in another

On a node of one joint (no `joints`) the services are the node's own: `examples/sdo.py /akd_node ''`.
"""

import sys

import rclpy
from rclpy.node import Node
from ros_helpers import call, init

from akd_ros.srv import SdoRead, SdoWrite

NODE = sys.argv[1] if len(sys.argv) > 1 else "/akd_node"
JOINT = sys.argv[2] if len(sys.argv) > 2 else "joint_2"
PREFIX = f"{NODE}/{JOINT}".rstrip("/")
WINDOW = 0x6065  # UNSIGNED32, counts

init()
client = Node("akd_sdo_client")


def read(index: int, subindex: int = 0) -> SdoRead.Response:
    return call(client, f"{PREFIX}/sdo_read", SdoRead, SdoRead.Request(index=index, subindex=subindex))


def write(index: int, value: int, size: int, subindex: int = 0) -> SdoWrite.Response:
    data = list(value.to_bytes(size, "little"))  # the object's bytes, little-endian
    return call(client, f"{PREFIX}/sdo_write", SdoWrite, SdoWrite.Request(index=index, subindex=subindex, data=data))


def value(response: SdoRead.Response) -> int:
    if not response.success:
        sys.exit(f"{PREFIX}/sdo_read: {response.message}")
    return int.from_bytes(bytes(response.data), "little")


was = value(read(WINDOW))
print(f"0x{WINDOW:04X}:00 following error window: {was} counts")
written = write(WINDOW, 1 << 20, 4)
print(f"0x{WINDOW:04X}:00 <- {1 << 20}: {'written' if written.success else written.message}")
print(f"0x{WINDOW:04X}:00 following error window: {value(read(WINDOW))} counts")
restored = write(WINDOW, was, 4)
print(f"0x{WINDOW:04X}:00 <- {was}: {'written' if restored.success else restored.message}")
missing = read(0x1234)
print(f"sdo_read refused: {missing.message}" if not missing.success else "0x1234:00: read")
client.destroy_node()
rclpy.shutdown()
sys.exit(0 if written.success and restored.success and not missing.success else 1)
