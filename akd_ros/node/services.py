"""Services: bus-wide ~/enable, ~/disable, ~/reset_fault, ~/quick_stop (std_srvs/Trigger) on every joint at once,
and per joint the same four and set_mode, arm_latch, sdo_read and sdo_write (the package's own) under ~/<joint>/
(on a node of one axis they are all under ~/, the four bus-wide ones serving its joint). Each answers with success
and a message saying what happened or why not, naming the joints that refused; none raises."""

from __future__ import annotations

from collections.abc import Callable

from akd_ros.axis import MODES, CommandError
from akd_ros.node.commands import Commands
from akd_ros.node.node_state import AXIS_ERRORS, NodeState, namespace
from akd_ros.node.publishing import EDGE_FALLING, EDGE_NAMES, EDGE_RISING
from akd_ros.node.transports.transport import Transport

REQUESTS = ("enable", "disable", "reset_fault", "quick_stop")
"""The Trigger services, bus-wide and per joint."""


class Services:
    """The node's services, in `group` (they may wait up to the Axis's time-outs)."""

    def __init__(self, transport: Transport, node_state: NodeState, commands: Commands, group) -> None:
        self._node_state = node_state
        self._logger = transport.logger
        for request in REQUESTS:
            transport.service(
                "std_srvs/srv/Trigger",
                f"~/{request}",
                self._trigger(f"~/{request}", lambda r=request: commands.request_all(r)),
                group,
            )
        for joint in node_state.joints:
            ns, name = namespace(node_state.settings, joint.name), joint.name
            if node_state.settings.joint_namespaces:
                for request in REQUESTS:
                    handler = self._trigger(f"{ns}{request}", lambda j=name, r=request: commands.request(j, r))
                    transport.service("std_srvs/srv/Trigger", f"{ns}{request}", handler, group)
            for kind, service, handler in (
                ("akd_ros/srv/SetMode", "set_mode", self._set_mode),
                ("akd_ros/srv/ArmLatch", "arm_latch", self._arm_latch),
                ("akd_ros/srv/SdoRead", "sdo_read", self._sdo_read),
                ("akd_ros/srv/SdoWrite", "sdo_write", self._sdo_write),
            ):
                callback = (lambda h, j: lambda request, response: h(j, request, response))(handler, name)
                transport.service(kind, f"{ns}{service}", callback, group)

    def _trigger(self, name: str, handler: Callable[[], tuple[bool, str]]):
        def callback(request, response):
            response.success, response.message = handler()
            # rclpy ties a severity to each logging call site: one call per severity.
            if response.success:
                self._logger.info(f"{name}: {response.message}")
            else:
                self._logger.warning(f"{name}: {response.message}")
            return response

        return callback

    def _set_mode(self, joint: str, request, response):
        try:
            axis = self._node_state.axis_for_request(joint)
            if request.mode not in MODES:
                raise CommandError(f"mode {request.mode!r} is not one of {', '.join(MODES)}")
            with self._node_state.lock:
                axis.set_mode(request.mode)
            response.success, response.message = True, f"mode {request.mode}"
        except AXIS_ERRORS as e:
            response.success, response.message = False, f"mode not changed: {e}"
        self._logger.info(f"set_mode of {joint}: {response.message}")
        return response

    def _arm_latch(self, joint: str, request, response):
        try:
            axis = self._node_state.axis_for_request(joint)
            if request.edge not in EDGE_NAMES:
                raise CommandError(
                    f"latch edge {request.edge}: allowed {EDGE_RISING} (rising) or {EDGE_FALLING} (falling)"
                )
            axis.arm_latch(request.channel, EDGE_NAMES[request.edge], request.arm)
            response.success = True
            response.message = (
                f"latch {request.channel} {'armed' if request.arm else 'disarmed'} on the "
                f"{EDGE_NAMES[request.edge]} edge"
            )
        except AXIS_ERRORS as e:
            response.success, response.message = False, f"latch not changed: {e}"
        return response

    def _sdo_read(self, joint: str, request, response):
        try:
            response.data = list(self._node_state.axis_for_request(joint).sdo_read(request.index, request.subindex))
            response.success, response.message = True, ""
        except AXIS_ERRORS as e:
            response.success, response.message = False, f"0x{request.index:04X}:{request.subindex:02X}: {e}"
        return response

    def _sdo_write(self, joint: str, request, response):
        try:
            self._node_state.axis_for_request(joint).sdo_write(request.index, request.subindex, bytes(request.data))
            response.success, response.message = True, ""
        except AXIS_ERRORS as e:
            response.success, response.message = False, f"0x{request.index:04X}:{request.subindex:02X}: {e}"
        return response
