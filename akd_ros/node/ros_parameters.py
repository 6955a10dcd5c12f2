"""The node's parameters on rclpy: each of `akd_ros.params.SCHEMA` declared with its ROS type and descriptor.

The schema and every check are `akd_ros.params`', which imports no ROS package; this module adds what only rclpy
has: the parameter types, the `ParameterDescriptor` (description, range or allowed values, read-only) that
`ros2 param describe` shows, and the declaration, which takes the values rcl read from the ROS arguments.
"""

from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter

from akd_ros.params import (
    SCHEMA,
    Settings,
    Spec,
    argument_sections,
    check_device_names,
    check_joint_names,
    device_specs,
    io_name_specs,
    joint_specs,
    refuse_single_joint_parameters,
    refuse_unknown,
    settings,
)


def parameter_type(spec: Spec) -> Parameter.Type:
    """The ROS parameter type of `spec`, from its default."""
    if spec.kind is list:
        return Parameter.Type.STRING_ARRAY
    return Parameter.Type.from_parameter_value(spec.default)


def descriptor(spec: Spec) -> ParameterDescriptor:
    """The descriptor `spec` is declared with (read-only: read once at start-up)."""
    kind = parameter_type(spec)
    described = ParameterDescriptor(name=spec.name, type=kind.value, description=spec.description, read_only=True)
    if spec.choices is not None:
        described.additional_constraints = spec.allowed()
        if kind == Parameter.Type.INTEGER:
            # The only integer choice set is direction's {-1, +1}: a range of step 2.
            described.integer_range = [
                IntegerRange(
                    from_value=min(spec.choices), to_value=max(spec.choices), step=max(spec.choices) - min(spec.choices)
                )
            ]
    elif spec.low is not None and kind == Parameter.Type.INTEGER:
        described.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)]
    elif spec.low is not None:
        described.floating_point_range = [FloatingPointRange(from_value=spec.low, to_value=spec.high, step=0.0)]
    return described


def declare(node, arguments: list[str], overrides: list[Parameter] = ()) -> Settings:
    """Declares every parameter on `node` (what the ROS arguments gave each checked first), with every joint's block
    (joints.<name>.*), every device's (devices.<name>.*) and every name given to an input or output (io.inputs.<name>,
    io.outputs.<name>), and gives
    the checked settings; raises ParameterError naming the first parameter that is wrong
    and what it allows.

    `arguments` are the command lines rcl read for the node (rclpy.init's and the node's own cli_args) and
    `overrides` the node's parameter_overrides: they tell which names were given, so that a name given but not
    declared is reported as unknown."""
    # Every section's parameters, whichever node it names: rcl decides which apply to this node, and _given tells.
    named = {name: value for section in argument_sections(arguments).values() for name, value in section.items()}
    named |= {parameter.name: parameter.value for parameter in overrides}
    top = {spec.name: _declare(node, spec, named) for spec in SCHEMA}
    joints = check_joint_names(top["joints"])
    devices = check_device_names(top["devices"], joints)
    refuse_single_joint_parameters(named, joints)
    values = dict(top)
    # A name of another node's section is among `named` too: only those given to this node are declared.
    io_names = [s for s in io_name_specs(named, joints) if _given(node, s.name).type_ != Parameter.Type.NOT_SET]
    for spec in [*joint_specs(joints, top), *io_names, *device_specs(devices)]:
        values[spec.name] = _declare(node, spec, named)
    refuse_unknown(
        [
            n
            for n in named
            if not node.has_parameter(n)
            and not n.startswith("qos_overrides.")
            and _given(node, n).type_ != Parameter.Type.NOT_SET
        ],
        joints,
        devices,
    )
    return settings(values)


def _declare(node, spec: Spec, named: dict[str, object]) -> object:
    """Declares `spec` on `node` with what the ROS arguments gave it, checked; its value."""
    given = _given(node, spec.name)
    # An empty YAML list arrives without a type, as nothing does.
    unset = given.type_ == Parameter.Type.NOT_SET and named.get(spec.name) != []
    value = spec.check(spec.default if unset else given.value)
    if value == []:
        node.declare_parameter(spec.name, Parameter.Type.STRING_ARRAY, descriptor(spec), ignore_override=True)
    else:
        node.declare_parameter(spec.name, value, descriptor(spec), ignore_override=True)
    return value


def _given(node, name: str) -> Parameter:
    """What the ROS arguments gave `name` on `node`, whatever its type (NOT_SET for nothing).

    rclpy hands a parameter's override to its declaration: declared with dynamic typing, it takes the value as the
    file spelt it, which this package then checks with its own messages; it is undeclared again at once."""
    parameter = node.declare_parameter(name, None, ParameterDescriptor(dynamic_typing=True))
    node.undeclare_parameter(name)
    return parameter
