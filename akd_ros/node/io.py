"""The drives' own I/O on ROS: each joint's ~/io (akd_ros/DriveIO), ~/set_outputs (akd_ros/SetOutputs), and what
/diagnostics says of a drive's I/O (`reasons`); and the devices' beside them: each device's ~/<device>/io
(akd_ros/DeviceIO), its outputs set through the same ~/set_outputs, whose `joint` then names the device.

~/io (~/<joint>/io on a node of joints) carries the digital inputs with the CiA 402 switches, the hardware enable as
the drive shows it, the analog input, and the outputs as last sent, with the names io.inputs and io.outputs give them.
It is made by the crate at io_rate for every joint from one snapshot of the cycle (every joint's I/O of the same cycle;
`akd_ros.node.publishing` hands the bytes over), and once more at each change of a joint's digital inputs or hardware
enable: from the cycle thread's event of that change, stamped with the cycle whose process image showed it, so an edge
is neither late by a publication period nor lost between two. The crate makes both (one DriveIO in one place), Python
wakes for them at publication rates or at the change, never per cycle, and both are recorded when the node records.

~/set_outputs writes one joint's digital outputs (by name or by the AKD's number) and analog output set-point into the
next cycle's process image, never by SDO. A request is checked whole first and refused with one line that names the
problem and what is allowed, changing nothing.

A device's ~/<device>/io carries every channel of its process data by name (its SII's, in snake case), inputs as read
and outputs as sent, each as a number (a bit 0 or 1): made by the crate at io_rate and once more at each change of
its inputs of one bit, from the cycle thread's event of it, as a joint's is. ~/set_outputs with `joint` naming a device
sets its output channels of one bit by name (`outputs`, `values`), every one or none.
"""

from __future__ import annotations

from akd_ros import _native
from akd_ros.axis import AxisIo, CommandError
from akd_ros.node.node_state import AXIS_ERRORS, NodeState, namespace
from akd_ros.node.publishing import Publishing, RecordedPublisher
from akd_ros.node.transports.transport import Qos, Transport
from akd_ros.params import JointSettings

# Statusword bit 11, internal limit active: the drive holds a command back (here: at a limit switch).
_INTERNAL_LIMIT = 1 << 11


def reasons(io: AxisIo, statusword: int) -> list[str]:
    """Why, as its I/O says, the drive will not enable or will not move one way: the hardware enable low, a limit
    switch active; in the drive's words (the objects and bits that say so). Empty when nothing holds it."""
    found = []
    if io.hardware_enable == "low":
        found.append(
            "hardware enable low: the drive shows a warning (statusword bit 7) and will not stay switched on "
            "(FBUS.PARAM05 bit 1 = 0 drops it to Switch on disabled while the input is low)"
        )
    holding = " and holds a command back (internal limit active, statusword bit 11)"
    for switch, bit, direction in (("positive_limit", 1, "positive"), ("negative_limit", 0, "negative")):
        if io.switches.get(switch):
            found.append(
                f"{direction} limit switch active (0x60FD bit {bit}): the drive stops moves in the {direction} "
                f"direction" + (holding if statusword & _INTERNAL_LIMIT else "")
            )
    return found


def named_levels(joint: JointSettings, io: AxisIo) -> dict[str, str]:
    """The levels of the inputs and outputs `joint` names, as /diagnostics' values show them: "input part_present (3)":
    "high"; none where the mapping does not carry them."""
    levels = {}
    for kind, names, values in (("input", joint.io_inputs, io.inputs), ("output", joint.io_outputs, io.outputs)):
        for name, number in (names or {}).items() if values else ():
            levels[f"{kind} {name} ({number})"] = "high" if values[number - 1] else "low"
    return levels


class Io:
    """Each joint's ~/io publisher, fed by `publishing`'s feed at io_rate and at each change, and ~/set_outputs in
    `requests`."""

    def __init__(self, transport: Transport, node_state: NodeState, requests, qos: Qos, publishing: Publishing) -> None:
        self._node_state = node_state
        self._logger = transport.logger
        self._joints = {j.name: j for j in node_state.joints}
        self.publishers = {
            j.name: RecordedPublisher(
                transport, "akd_ros/msg/DriveIO", f"{namespace(node_state.settings, j.name)}io", qos, node_state
            )
            for j in node_state.joints
        }
        """Each joint's ~/io publisher, by its name."""
        self._devices = {d.name: d for d in node_state.settings.devices}
        self.device_publishers = {
            d.name: RecordedPublisher(transport, "akd_ros/msg/DeviceIO", f"~/{d.name}/io", qos, node_state)
            for d in node_state.settings.devices
        }
        """Each device's ~/<device>/io publisher, by its name."""
        publishing.publish_drive_io(self.publishers, 1.0 / node_state.settings.io_rate)
        publishing.publish_device_io(self.device_publishers, 1.0 / node_state.settings.io_rate)
        transport.service("akd_ros/srv/SetOutputs", "~/set_outputs", self._set_outputs, requests)

    def _joint_of(self, joint: str) -> str:
        """The joint a request names ('' on a node of one joint: that one); CommandError otherwise."""
        if joint in self._joints or (not joint and len(self._joints) == 1):
            return joint or next(iter(self._joints))
        devices = f", nor of its devices: {', '.join(self._devices)}" if self._devices else ""
        raise CommandError(f"joint {joint!r} is not one of this node's joints: {', '.join(self._joints)}{devices}")

    def _set_device_outputs(self, request, response):
        """~/set_outputs of the device `request.joint` names: its output channels of one bit by name."""
        name = request.joint
        outputs, values = list(request.outputs), list(request.values)
        if request.set_analog_output:
            raise CommandError(
                f"device {name} takes its outputs by channel name (outputs, values); set_analog_output is a joint's"
            )
        if len(outputs) != len(values):
            raise CommandError(f"{len(outputs)} outputs with {len(values)} values: give one value per output")
        if not outputs:
            raise CommandError(f"nothing to set: give outputs of device {name} with their values")
        twice = sorted({o for o in outputs if outputs.count(o) > 1})
        if twice:
            raise CommandError(f"output {', '.join(twice)} of device {name} is given twice")
        device = self._node_state.device_for_request(name)
        levels = {output: bool(value) for output, value in zip(outputs, values, strict=True)}
        with self._node_state.lock:
            device.set_outputs(levels)
        done = ", ".join(f"{output} {'high' if high else 'low'}" for output, high in levels.items())
        response.success, response.message = True, f"{name}: {done} from the next cycle"

    def _levels(self, joint: str, outputs: list[str], values: list[bool]) -> dict[int, bool]:
        """The outputs a request names (by a name of io.outputs or the AKD's number) with their levels; CommandError
        for a name the joint does not have, an output given twice, or a count of values that does not match."""
        if len(outputs) != len(values):
            raise CommandError(f"{len(outputs)} outputs with {len(values)} values: give one value per output")
        names = self._joints[joint].io_outputs or {}
        levels: dict[int, bool] = {}
        for output, value in zip(outputs, values, strict=True):
            # ASCII digits only: str.isdecimal() and int() also take other scripts' digits (Arabic-Indic, full-width).
            number = names.get(output, int(output) if output.isascii() and output.isdigit() else None)
            if number is None:
                numbers = ", ".join(str(n) for n in range(1, _native.IO_OUTPUT_COUNT + 1))
                allowed = f"its names ({', '.join(names)}) or " if names else ""
                raise CommandError(
                    f"output {output!r} of joint {joint}: allowed {allowed}the AKD's output numbers {numbers}"
                )
            if number in levels:
                raise CommandError(f"output {output!r} of joint {joint} (output {number}) is given twice")
            levels[number] = bool(value)
        return levels

    def _set_outputs(self, request, response):
        try:
            if request.joint in self._devices:
                self._set_device_outputs(request, response)
                self._logger.info(f"~/set_outputs: {response.message}")
                return response
            joint = self._joint_of(request.joint)
            levels = self._levels(joint, list(request.outputs), list(request.values))
            analog = request.analog_output if request.set_analog_output else None
            if not levels and analog is None:
                raise CommandError("nothing to set: give outputs with their values, or set_analog_output")
            axis = self._node_state.axis_for_request(joint)
            with self._node_state.lock:
                axis.set_outputs(levels, analog)
            done = [f"output {n} {'high' if high else 'low'}" for n, high in sorted(levels.items())]
            done += [] if analog is None else [f"analog output {analog:g} V"]
            response.success, response.message = True, f"{joint}: {', '.join(done)} from the next cycle"
            self._logger.info(f"~/set_outputs: {response.message}")
        except AXIS_ERRORS as e:
            response.success, response.message = False, f"outputs not set: {e}"
            self._logger.warning(f"~/set_outputs: {response.message}")
        return response
