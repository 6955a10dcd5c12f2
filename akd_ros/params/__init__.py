"""The parameters of `akd_node`: their schema (type, default, range, description) and their checks (`schema`), the
parameters file and -p arguments read as rcl reads them (`reader`), and the settings the node runs with, made of them
(`node_settings`); every public name of the three is here, as `akd_ros.params.NAME`.

This module imports no ROS package: `read_parameters_file` and `read_arguments` read a parameters file and -p
overrides as rcl does (with PyYAML), and `settings` checks them, so the node runs without ROS (transport zenoh).
Over rclpy, `akd_ros.node.ros_parameters.declare` declares every parameter on the node with a `ParameterDescriptor`
carrying its description, its range (numbers) or its allowed values (strings, in `additional_constraints`), so
`ros2 param describe /akd_node NAME` tells what a file may say. All are read-only: they are read once, at start-up;
change the file and restart the node.

A parameters file is checked before anything reaches the bus: an unknown name, a wrong type, a value outside its
range or its allowed values, an unknown PDO mapping, a cycle time below the AKD's 250 µs or a network interface
that does not exist each raise `ParameterError`, whose message names the parameter and what is allowed. A whole
number where a real number is expected (``gear_ratio: 2``) is taken as that real number.

PDO mapping (`mapping`):

- ``default``: the Axis's own flexible mapping, which carries everything every mode needs;
- ``io``: akd_ros's flexible mapping with the drive's own I/O (digital and analog inputs and outputs), which carries
  every mode's command but interpolated position's (docs/io.md);
- ``RX/TX``: one of the AKD's fixed mappings each way, e.g. ``0x1724/0x1B26`` (cyclic synchronous position);
- ``flexible``: the PDOs given by `mapping.rx` and `mapping.tx`, one string per PDO, its entries separated by
  spaces as ``INDEX:SUB/BITS``, e.g. ``["0x6040:00/16 0x60C1:01/32", "0x60FF:00/32"]``.

Every mapping is tried on a virtual AKD before it is accepted; it refuses what the real drive refuses (unknown
fixed mappings, objects that cannot be mapped, PDOs over 8 bytes, odd lengths). Each joint's settings say which of the
drive's I/O its mapping carries (`JointSettings.io_carried`), and names given to inputs or outputs it does not carry
are refused, naming the mappings that would.

Names for a joint's digital inputs and outputs are parameters of their own, as a map in the file:
``io: {inputs: {part_present: 3}, outputs: {brake_release: 1}}`` gives io.inputs.part_present and
io.outputs.brake_release (`IO_NAME_SPECS`); top-level names apply to every joint, a joint's block adds its own.
"""

from __future__ import annotations

# Imported to be re-exported, each name once (hence F401): every public name of the three, as akd_ros.params.NAME.
from akd_ros.params.node_settings import (  # noqa: F401
    DeviceSettings,
    JointSettings,
    Settings,
    check_eoe_bridge,
    device_settings,
    joint_settings,
    settings,
    transport_of,
)
from akd_ros.params.reader import (  # noqa: F401
    argument_sections,
    read_arguments,
    read_parameters_file,
)
from akd_ros.params.schema import (  # noqa: F401
    COMMAND_TIMEOUT_POLICIES,
    CYCLE_TIME_RANGE,
    DC_CHOICES,
    DEVICE_SPECS,
    DOOR_ROLES,
    EDGES,
    FAULT_RESET_POLICIES,
    IO_NAME_SPECS,
    JOINT_NAME,
    SCHEMA,
    SPECS,
    TRANSPORTS,
    ParameterError,
    Spec,
    check_device_names,
    check_doors,
    check_interface_address,
    check_joint_names,
    check_link,
    check_live_view,
    check_mapping,
    check_names,
    device_specs,
    io_name_specs,
    io_names,
    joint_specs,
    parse_latches,
    parse_limits,
    parse_mapping,
    refuse_single_joint_parameters,
    refuse_unknown,
)
