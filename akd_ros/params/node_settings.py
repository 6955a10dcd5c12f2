"""The node's settings: `Settings` with a `JointSettings` per joint and a `DeviceSettings` per device, its checked
parameters in the forms the Bus and its Axis take, made by `settings` of what `akd_ros.params.reader` reads; and
`transport_of`, the transport the parameters choose.

A parameter is named once: its setting is the field of its name with each dot an underscore (`field_name`), filled
from SCHEMA in one loop (`made_of`) unless the setting is made of it (a link checked, a mapping parsed), and only the
parameters that make a setting of several (a joint's units, limits and name, the cycle thread's realtime, record and
live_view) have no field of their own."""

from __future__ import annotations

import dataclasses
import importlib.util
from dataclasses import dataclass

from akd_ros import _native
from akd_ros.axis import DriveConfig
from akd_ros.bus import CommandError, check
from akd_ros.device import DeviceConfig
from akd_ros.params.schema import (
    DC_CHOICES,
    DOOR_ROLES,
    SCHEMA,
    SPECS,
    ParameterError,
    check_device_names,
    check_doors,
    check_interface_address,
    check_joint_names,
    check_link,
    check_live_view,
    check_mapping,
    device_specs,
    io_names,
    joint_specs,
    parse_latches,
    parse_limits,
    parse_mapping,
)
from akd_ros.units import Limits, Units


@dataclass(frozen=True)
class JointSettings:
    """One joint's checked parameters, in the forms the Bus and its Axis take; a field named after a parameter
    (`field_name`) holds it."""

    name: str
    slave: int | None
    """The drive's position on the bus; None when `alias` finds it."""
    alias: int | None
    """The station alias that finds the drive, None to use `slave`."""
    mode: str
    mapping: tuple[object, object] | None
    """(rx, tx) for `akd_ros.DriveConfig`, None for its default mapping."""
    units: Units
    limits: Limits
    latch_arm: tuple[tuple[int, str], ...]
    """(channel, edge) of each latch armed at activate."""
    fault_reset: str
    command_timeout: float
    command_timeout_policy: str
    homing_method: str
    """'drive' (homed by ~/home) or 'none' (homed from the start)."""
    homing_required: bool
    """Whether motion commands are refused until the joint is homed."""
    homing_timeout: float
    constraints_trajectory: float
    """The default path position tolerance, SI (0: not judged)."""
    constraints_goal: float
    """The default goal position tolerance, SI (0: not judged)."""
    constraints_stopped_velocity_tolerance: float
    """The default goal velocity tolerance, SI/s (0: not judged)."""
    trajectory_stop_deceleration: float
    """How a stopped FollowJointTrajectory goal decelerates, SI/s²."""
    eoe_ip: str | None
    """The drive's address and prefix for EoE (A.B.C.D/N), None for none."""
    io_carried: dict[str, bool]
    """What the mapping carries of the drive's I/O (`_native.mapping_io`): digital_inputs, analog_input,
    digital_outputs, analog_output."""
    io_inputs: dict[str, int]
    """The names given to digital inputs (io.inputs.<name>), with their numbers."""
    io_outputs: dict[str, int]
    """The names given to digital outputs (io.outputs.<name>), with their numbers."""
    io_analog_scale: float
    """Volts per count of the analog input and output."""

    def drive(self) -> DriveConfig:
        """The joint's drive as a Bus takes it."""
        return DriveConfig(
            slave=self.slave,
            alias=self.alias,
            name=self.name,
            mode=self.mode,
            units=self.units,
            limits=self.limits,
            mapping=self.mapping,
            eoe_ip=self.eoe_ip,
            analog_scale=self.io_analog_scale,
        )

    def describe_io(self) -> str:
        """What the joint's mapping carries of its drive's I/O, in words, for the log."""
        carried = [name.replace("_", " ") for name, has in (self.io_carried or {}).items() if has]
        return ", ".join(carried) if carried else "none of the drive's I/O"


@dataclass(frozen=True)
class DeviceSettings:
    """One device's checked parameters."""

    name: str
    slave: int
    product: str | None
    """What it must be (its order number), None for anything."""

    def device(self) -> DeviceConfig:
        """The device as a Bus takes it."""
        return DeviceConfig(slave=self.slave, name=self.name, product=self.product)


@dataclass(frozen=True)
class Settings:
    """The node's checked parameters, in the forms the Bus takes; a field named after a parameter (`field_name`) holds
    it."""

    link: str
    cycle_time: float
    dc: bool | None
    """The Bus's `dc`: True on, False off, None the link's default."""
    dc_shift: float
    fault_reaction: str
    joints: tuple[JointSettings, ...]
    """Every joint, in the order of the joints parameter (one, joint_name, without it)."""
    joint_namespaces: bool
    """Whether each joint's topics and services go under ~/<joint>/ (joints given) rather than ~/ (one joint)."""
    joint_states_rate: float
    homing_sequence: str
    """How ~/home homes several joints: 'together' or 'one_by_one'."""
    constraints_goal_time: float
    """The default goal time tolerance of ~/follow_joint_trajectory, s."""
    follow_joint_trajectory_feedback_rate: float
    """Hz."""
    status_rate: float
    diagnostics_rate: float
    io_rate: float
    realtime: _native.RealTime
    """The cycle thread's rt.* parameters: priority, CPU, locked memory, wake-up latency, pipelined frames."""
    record: dict[str, object] | None
    """The Recorder's folder, decimation and black_box_seconds; None when recording is off."""
    autostart: bool
    enable_on_start: bool
    transport: str
    """"rclpy", "zenoh" or "both" (`transport_of` picks it for the node)."""
    zenoh_config: str | None
    """The Zenoh JSON5 file of the session, None for rmw_zenoh's default."""
    zenoh_connect: tuple[str, ...]
    """The endpoints the Zenoh session connects to, none to keep the configuration's."""
    eoe_tap: str | None = None
    """The TAP interface bridged to the joints' EoE, None for none."""
    eoe_host: str | None = None
    """The TAP interface's address (A.B.C.D/N), None for none."""
    live_view: tuple[str, int] | None = None
    """The live view's (address, port) (live_view.*), None when off."""
    devices: tuple[DeviceSettings, ...] = ()
    """Every device beside the drives, in the order of the devices parameter."""
    doors: tuple[str, ...] = DOOR_ROLES[:2]
    """The roles whose doors the node has, in DOOR_ROLES' order."""

    def bus_options(self) -> dict[str, object]:
        """The Bus's keyword arguments (all but the link and the drives) as these settings give them: akd_node's bus."""
        return {
            "period": self.cycle_time,
            "realtime": self.realtime,
            "fault_reaction": self.fault_reaction,
            "dc": self.dc,
            "dc_shift": self.dc_shift,
        }


def field_name(parameter: str) -> str:
    """The field of `Settings` or `JointSettings` that holds the parameter named `parameter`: its name with each dot
    an underscore (homing.sequence: homing_sequence)."""
    return parameter.replace(".", "_")


def made_of(cls: type, values: dict[str, object], per_joint: bool, **made: object):
    """`cls` (`Settings`, or with `per_joint` `JointSettings`) of the fields `made` and, for each other field that holds
    a parameter of SCHEMA (its own, or each joint's with `per_joint`), that parameter's checked value in `values`."""
    fields = {field.name for field in dataclasses.fields(cls)} - made.keys()
    given = {
        field_name(spec.name): values[spec.name]
        for spec in SCHEMA
        if spec.per_joint == per_joint and field_name(spec.name) in fields
    }
    return cls(**given, **made)


def settings(values: dict[str, object]) -> Settings:
    """The settings for `values` (the parameters of SCHEMA by name, and with joints each joint's block
    joints.<name>.<parameter>, missing ones taking their defaults: what `read_parameters_file` or `read_arguments`
    gives); raises ParameterError."""
    top = {spec.name: spec.check(values.get(spec.name, spec.default)) for spec in SCHEMA}
    link = check_link(top["link"])
    if not abs(top["dc_shift"]) < top["cycle_time"]:
        raise ParameterError(
            f"parameter dc_shift must be less than one cycle_time ({top['cycle_time']} s) either way, "
            f"got {top['dc_shift']}"
        )
    names = check_joint_names(top["joints"])
    if names:
        blocks = {}
        for spec in joint_specs(names, top):
            blocks[spec.name] = spec.check(values.get(spec.name, spec.default))
        joints = tuple(
            joint_settings(
                name,
                f"joints.{name}.",
                {s.name: blocks[f"joints.{name}.{s.name}"] for s in SCHEMA if s.per_joint},
                (io_names(values, name, "inputs"), io_names(values, name, "outputs")),
            )
            for name in names
        )
    else:
        io = (io_names(values, None, "inputs"), io_names(values, None, "outputs"))
        joints = (joint_settings(top["joint_name"], "", top, io),)
    devices = device_settings(values, check_device_names(top["devices"], names))
    try:
        check([j.drive() for j in joints], top["fault_reaction"], top["cycle_time"], top["dc_shift"])
    except CommandError as e:
        raise ParameterError(f"parameters joints.<name>.slave/alias: {e}") from None
    try:
        drives = [j.drive() for j in joints]
        check(drives, top["fault_reaction"], top["cycle_time"], top["dc_shift"], [d.device() for d in devices])
    except CommandError as e:
        # The joints passed alone: what is wrong is a device's.
        raise ParameterError(f"parameters devices.<name>.slave: {e}") from None
    eoe_tap, eoe_host = check_eoe_bridge(top["eoe.tap"], top["eoe.host"], joints)
    return made_of(
        Settings,
        top,
        per_joint=False,
        link=link,
        dc=DC_CHOICES[top["dc"]],
        joints=joints,
        joint_namespaces=bool(names),
        realtime=_native.RealTime(
            priority=top["rt.priority"] or None,
            cpu=None if top["rt.cpu"] < 0 else top["rt.cpu"],
            lock_memory=top["rt.lock_memory"],
            cpu_latency_us=None if top["rt.cpu_latency_us"] < 0 else top["rt.cpu_latency_us"],
            pipelined=top["rt.pipelined"],
        ),
        record={
            "folder": top["record.folder"],
            "decimation": top["record.decimation"],
            "black_box_seconds": top["record.black_box_seconds"],
        }
        if top["record.enabled"]
        else None,
        zenoh_config=top["zenoh.config"] or None,
        zenoh_connect=tuple(top["zenoh.connect"]),
        eoe_tap=eoe_tap,
        eoe_host=eoe_host,
        live_view=check_live_view(top["live_view.address"], top["live_view.port"]),
        devices=devices,
        doors=check_doors(top["doors"]),
    )


def device_settings(values: dict[str, object], devices: list[str]) -> tuple[DeviceSettings, ...]:
    """Each device of `devices` of its block's checked parameters in `values`; ParameterError for one whose slave is
    not given."""
    found = []
    for name in devices:
        block = {spec.name: spec.check(values.get(spec.name, spec.default)) for spec in device_specs([name])}
        slave = block[f"devices.{name}.slave"]
        if slave < 0:
            raise ParameterError(
                f"parameter devices.{name}.slave must be given: the device's position on the bus, 0..65535 from the "
                "master (akd-scan LINK lists the line)"
            )
        found.append(DeviceSettings(name, slave, block[f"devices.{name}.product"] or None))
    return tuple(found)


def transport_of(given: dict[str, object]) -> str:
    """The transport the parameters `given` (`read_arguments`) choose: theirs, checked; without one, rclpy where it
    imports and zenoh where it does not (a controller with no ROS install)."""
    if "transport" in given:
        return SPECS["transport"].check(given["transport"])
    try:
        found = importlib.util.find_spec("rclpy") is not None
    except ImportError:
        found = False
    return "rclpy" if found else "zenoh"


def joint_settings(
    name: str, prefix: str, values: dict[str, object], io: tuple[dict[str, int], dict[str, int]] = ({}, {})
) -> JointSettings:
    """The joint `name` of its checked parameters `values` (by their top-level names) and the names `io` gives its
    inputs and outputs, whose messages name each parameter with `prefix` ("" at the top level, "joints.<name>." in a
    block); raises ParameterError."""
    from akd_ros import _native

    mapping = parse_mapping(values["mapping"], values["mapping.rx"], values["mapping.tx"], prefix)
    if mapping is not None:
        check_mapping(mapping, prefix)
    carried = _native.mapping_io(*(mapping or _native.DEFAULT_MAPPING))
    for kind, names, needs, what in (
        ("inputs", io[0], "digital_inputs", "digital inputs (0x60FD)"),
        ("outputs", io[1], "digital_outputs", "digital outputs (0x60FE:01)"),
    ):
        if names and not carried[needs]:
            raise ParameterError(
                f"parameters io.{kind}.* of joint {name}: its mapping {values['mapping']!r} carries no {what}; "
                f"mappings that do with mode {values['mode']}: {_native.io_mappings_in_words(values['mode'], needs)}"
            )
    lead = values["lead"] or None
    if values["axis"] == "rotary" and lead is not None:
        raise ParameterError(
            f"parameter {prefix}lead applies to a linear axis only; with {prefix}axis 'rotary' it must be 0, got {lead}"
        )
    try:
        units = Units(
            values["counts_per_revolution"],
            values["gear_ratio"],
            values["direction"],
            values["offset"],
            values["axis"],
            lead,
            values["peak_torque"],
        )
    except ValueError as e:
        raise ParameterError(
            f"parameters {prefix}axis/{prefix}lead: {e} (lead > 0 with axis 'linear', lead 0 with 'rotary')"
        ) from None
    return made_of(
        JointSettings,
        values,
        per_joint=True,
        name=name,
        slave=None if values["alias"] >= 0 else values["slave"],
        alias=None if values["alias"] < 0 else values["alias"],
        mapping=mapping,
        units=units,
        limits=parse_limits(values, prefix),
        latch_arm=parse_latches(values["latch.arm"], prefix),
        eoe_ip=check_interface_address(f"{prefix}eoe.ip", values["eoe.ip"]),
        io_carried=dict(carried),
        io_inputs=io[0],
        io_outputs=io[1],
    )


def check_eoe_bridge(tap: str, host: str, joints: tuple[JointSettings, ...]) -> tuple[str | None, str | None]:
    """(eoe.tap, eoe.host) checked, None for ''; ParameterError."""
    # What Linux takes as an interface name (dev_valid_name), and "%d" for the kernel to number.
    if tap and (len(tap.encode()) > 15 or tap in (".", "..") or any(c in "/:" or c.isspace() for c in tap)):
        raise ParameterError(
            "parameter eoe.tap must be a network interface name of 1 to 15 bytes without '/', ':' or blanks "
            f"(e.g. akd-eoe0), or '', got {tap!r}"
        )
    address = check_interface_address("eoe.host", host)
    if address is not None and not tap:
        raise ParameterError("parameter eoe.host is the address of eoe.tap: give eoe.tap too, or eoe.host ''")
    if tap and not any(j.eoe_ip for j in joints):
        raise ParameterError("parameter eoe.tap bridges to the joints' eoe.ip: give at least one joint an eoe.ip")
    return tap or None, address
