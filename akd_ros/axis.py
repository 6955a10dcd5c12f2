"""`Axis`: one AKD on EtherCAT from Python, without ROS.

An Axis is one drive of an `akd_ros.Bus` (`bus.axes`), which owns the master and the one cycle thread.
`Axis(link, slave=...)` is a bus of one that the Axis owns: it opens a link (``"sim"`` for the built-in virtual AKD,
``"udp://HOST:PORT"`` for `akd-sim`, or a network interface), brings the drive to Op with a process-data mapping that
carries what it needs, and starts the native cycle thread. Everything at its surface is in SI units of the load
(`akd_ros.units.Units`): positions in rad (m on a linear axis), velocities in rad/s (m/s), torques in N·m (N).

Nothing moves unless commanded: enabling holds the target at the actual position, and so does every mode change,
until a command is written. Commands are checked before they reach the drive: NaN and infinite values are refused,
limits clamp or refuse as configured (`akd_ros.units.Limits`), and a command for another mode than the active one is
refused. Each refusal is a `CommandError` naming the problem and what is allowed; nothing is sent then.

Latch captures and faults arrive as events from the cycle thread, stamped with the cycle that saw them; `latch_events`
and `fault_events` hand them out once each, and so does `input_events` each change of the drive's digital inputs. The
set-point handshake of profile position and homing, and the command time-out (`set_command_timeout`), run in the cycle
thread too; `command_timeout_events` hands out each time-out once.

The drive's own I/O (`io`: digital inputs with the limit and home switches, the hardware enable as the drive shows it,
the analog input, the outputs as last sent) is read from the cycle's snapshot where the mapping carries it;
`set_outputs` writes the digital outputs and the analog output set-point into the next cycle's process image.

Distributed clocks (`dc`, `dc_shift`) are set for the whole line by its `Bus`; `Axis(link, ...)` hands them to its bus
of one, as it does `period`.
"""

from __future__ import annotations

import collections
import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass

from akd_ros import _native
from akd_ros.bus import _MODES, MODES, REQUESTS, Bus, CommandError, check_mode
from akd_ros.units import Limits, Units

MODE_NAMES = {code: name for name, code in MODES.items()}

DEFAULT_RX, DEFAULT_TX = _native.DEFAULT_MAPPING
"""The mapping an Axis takes unless given one (`_native.DEFAULT_MAPPING`): everything every mode needs."""
ANALOG_VOLTS_PER_COUNT = _native.ANALOG_VOLTS_PER_COUNT
"""Volts per count of the analog input 0x3470:04 and output 0x3470:03 unless a drive is given its own: ±10 V over the
16-bit range, assumed (the manuals give no scaling)."""

INPUT_EVENTS_KEPT = 4096
"""Changes of the digital inputs an Axis keeps until `input_events` takes them; older ones are dropped."""
# Velocity below which an enabled axis counts as standing still for a mode change, in counts/s (about 0.4 °/s at
# 2^20 counts per revolution).
STANDSTILL_COUNTS_PER_S = 1000


@dataclass(frozen=True)
class DriveConfig:
    """One drive of a `Bus`: where it is (`slave`, its position on the line, or `alias`, its station alias: one of
    them), its name (``"slave_<position>"`` unless given), its mode of operation at the start, its `Units` and
    `Limits`, its process-data mapping (`DEFAULT_RX`, `DEFAULT_TX` unless given), its IP address for EoE
    (``"A.B.C.D/N"``, set by Set IP Parameter in PreOp; None for none) and the volts per count of its analog input
    and output (`ANALOG_VOLTS_PER_COUNT` unless given)."""

    slave: int | None = None
    alias: int | None = None
    name: str | None = None
    mode: str = "interpolated_position"
    units: Units | None = None
    limits: Limits | None = None
    mapping: tuple[object, object] | None = None
    eoe_ip: str | None = None
    analog_scale: float | None = None

    def attach(self, bus: Bus, slave: int) -> Axis:
        """The Axis of this drive on `bus`, at position `slave`; the Bus calls it once the line is in Op."""
        axis = Axis.__new__(Axis)
        axis._attach(bus, slave, self)
        return axis


@dataclass(frozen=True)
class _ThisAxis(DriveConfig):
    """The one drive of `Axis(link, ...)`: the Bus attaches the Axis being made rather than a new one."""

    axis: Axis | None = None

    def attach(self, bus: Bus, slave: int) -> Axis:
        self.axis._attach(bus, slave, self)
        return self.axis


@dataclass(frozen=True)
class AxisState:
    """One cycle's view of the axis, in SI units (rad, rad/s, N·m; m, m/s, N on a linear axis)."""

    cycle: int
    """The cycle it was taken in (from 1)."""
    time_ns: int
    """That cycle's wake-up time on the monotonic clock."""
    fresh: bool
    """Whether that cycle's exchange succeeded (else the values are the last good ones)."""
    state: _native.Ds402State | None
    """The CiA 402 state (`Ds402State.OPERATION_ENABLED`, ...), None for a statusword that shows none. Earlier
    versions gave the state's name (a str): it prints as that name, but compares equal only to a member."""
    statusword: int
    mode: str | None
    """The mode the drive shows (0x6061), by name."""
    position: float
    velocity: float | None
    torque: float | None
    following_error: float | None
    position_counts: int
    """The actual position in counts, unwrapped across the 32-bit wrap."""
    request: _native.DriveRequest | None
    """The last request (`DriveRequest.ENABLE`, `DISABLE`, `QUICK_STOP`, `FAULT_RESET`; printed: "enable", "disable",
    "quick_stop", "reset_fault")."""
    progress: _native.RequestProgress
    """`RequestProgress.IDLE`, `IN_PROGRESS`, `DONE`, `STUCK` or `LOST` (printed: "idle", ..., "lost")."""
    reason: str | None
    """Why a request is stuck or lost, from the statusword."""
    digital_inputs: int | None = None


@dataclass(frozen=True)
class AxisIo:
    """One cycle's view of the drive's own I/O, where its mapping carries it (else empty, or None)."""

    cycle: int
    """The cycle it was taken in (from 1); for an input event, the cycle whose inputs showed the change."""
    time_ns: int
    """That cycle's wake-up time on the monotonic clock."""
    fresh: bool
    digital_inputs: int | None
    """0x60FD as the drive reports it."""
    switches: dict[str, bool]
    """0x60FD bits 0..3 by name (negative_limit, positive_limit, home_switch, interlock): whether each is active."""
    inputs: tuple[bool, ...]
    """The AKD's digital inputs 1..7, input 1 first."""
    hardware_enable: str
    """"high", "low" or "unknown", as the statusword shows it."""
    statusword: int | None
    """0x6041 of that cycle, which shows the hardware enable (None where the mapping does not carry it)."""
    analog_input: float | None
    """V."""
    digital_outputs: int | None
    """0x60FE:01 as last sent."""
    outputs: tuple[bool, ...]
    """The AKD's digital outputs 1..2 as last sent, output 1 first."""
    analog_output: float | None
    """V, as last sent."""


@dataclass(frozen=True)
class LatchEvent:
    """One position capture."""

    cycle: int
    time_ns: int
    channel: int
    """Latch 1 or 2."""
    edge: str
    """"rising" or "falling"."""
    position: float
    """The captured position in SI units."""
    position_counts: int


FaultEvent = _native.FaultEvent
"""One fault and what the cycle thread did about it, as the crate makes it (`_native.FaultEvent`)."""


@dataclass(frozen=True)
class CommandTimeoutEvent:
    """A velocity or torque stream that stopped for longer than the command time-out, and what the cycle thread did."""

    cycle: int
    time_ns: int
    command: str
    """"velocity" or "torque"."""
    timeout: float
    """The time-out in s."""
    value: float
    """The last command in SI units (rad/s, N·m; m/s, N on a linear axis)."""
    value_drive: int
    """The same in drive units (counts/s, 0.1 % of peak torque)."""
    statusword: int
    ds402_state: _native.Ds402State | None
    action: str
    """"hold" (halted until the next command) or "quick_stop" (until enabled again)."""
    text: str
    """What was done, e.g. "halted, holding until the next command"."""

    def describe(self, how_to_enable: str = "call Axis.enable() to go on") -> str:
        """One line for a log; after a quick stop it ends with `how_to_enable`, which depends on who reads it."""
        after = f"; {how_to_enable}" if self.action == "quick_stop" else ""
        return (
            f"no {self.command} command for {self.timeout:g} s (command_timeout) while commanding {self.value:g}: "
            f"{self.text}{after}"
        )


class Axis:
    """One AKD axis, commanded in SI units: a drive of a `Bus`, or with `Axis(link, ...)` a bus of one of its own.

    Use as a context manager or call `close()`: it disables the drive and, for a bus of its own, stops the cycle and
    returns the bus to Init.
    """

    def __init__(
        self,
        link: str = "sim",
        *,
        slave: int = 0,
        alias: int | None = None,
        period: float = 0.001,
        mode: str = "interpolated_position",
        units: Units | None = None,
        limits: Limits | None = None,
        mapping: tuple[object, object] | None = None,
        realtime: _native.RealTime | None = None,
        request_timeout: float = 1.0,
        frame_timeout: float = 0.1,
        dc: bool | None = None,
        dc_shift: float = 0.0,
    ) -> None:
        drive = _ThisAxis(
            slave=None if alias is not None else slave,
            alias=alias,
            mode=mode,
            units=units,
            limits=limits,
            mapping=mapping,
            axis=self,
        )
        Bus(
            link,
            [drive],
            period=period,
            realtime=realtime,
            request_timeout=request_timeout,
            frame_timeout=frame_timeout,
            dc=dc,
            dc_shift=dc_shift,
            # Alone on its bus, the drive reacts to its own faults only, as it always did.
            fault_reaction="joint",
        )
        self._owns_bus = True

    def _attach(self, bus: Bus, slave: int, drive: DriveConfig) -> None:
        self._bus = bus
        self._owns_bus = False
        self._closed = False
        self.slave = slave
        """The drive's position on the bus (found from `alias` when given)."""
        self.name = drive.name or f"slave_{slave}"
        """The drive's name on its bus."""
        self.serial_number: int = bus.slaves[slave]["serial_number"]
        """The drive's serial number, from its SII."""
        self.units = drive.units or Units()
        self.limits = drive.limits or Limits()
        self.simulator = bus.simulator
        """For the built-in virtual AKD: its `Simulator` (fault injection, hardware enable, input toggles)."""
        mapping = bus.cycle.mapping(slave)
        self._outputs = {(index, subindex) for index, subindex, _, _ in mapping["outputs"]}
        self.analog_scale = drive.analog_scale or ANALOG_VOLTS_PER_COUNT
        """Volts per count of the analog input and output."""
        # Bounded: an input that chatters while nobody takes its changes must not fill the memory; the oldest go.
        self._input_events: collections.deque[AxisIo] = collections.deque(maxlen=INPUT_EVENTS_KEPT)
        mapped = self._outputs | {(index, subindex) for index, subindex, _, _ in mapping["inputs"]}
        self.drive_scaling: _native.PositionScaling | None = bus.scalings.get(slave)
        """The drive's position scaling, read at the start (`_native.Master.position_scaling`); None for a drive
        without the DS402 scaling objects."""
        mismatch = self.units.scale_mismatch(self.drive_scaling, sorted(mapped))
        if mismatch is not None:
            raise CommandError(f"{self.name} (drive {slave}): {mismatch}")
        self._mode = drive.mode
        self._latches: collections.deque[LatchEvent] = collections.deque()
        self._faults: collections.deque[FaultEvent] = collections.deque()
        self._command_timeouts: collections.deque[CommandTimeoutEvent] = collections.deque()
        self._unwrap = _native.PositionUnwrap()
        self._commanded: dict[str, float] = {}
        self._hand_down_limits()

    def _hand_down_limits(self) -> None:
        """Hands the limits down to the cycle, which judges every motion of the drive by them from then on
        (trajectories, and the steps of cyclic position set-points), and words its refusals in this axis's units."""
        low, high = self.position_limits_counts()
        open_ends = {-(2.0**31), 2.0**31 - 1}
        counts_per_si = 1 / abs(self.units.si_per_count)
        speeds = [
            None if v is None else v * counts_per_si for v in (self.limits.max_velocity, self.limits.max_acceleration)
        ]
        self._bus.cycle.set_joint_limits(
            self.slave,
            self.name,
            (None if low in open_ends else low, None if high in open_ends else high),
            *speeds,
            units=self.units,
        )

    # --- life cycle ---------------------------------------------------------------------------------------------

    @property
    def bus(self) -> Bus:
        """The bus the drive is on."""
        return self._bus

    @property
    def warnings(self) -> list[str]:
        """The bus's warnings (`Bus.warnings`)."""
        return self._bus.warnings

    def close(self) -> str | None:
        """Disables the drive (waiting up to a second); an Axis with a bus of its own then closes the bus (cycle
        stopped, bus to Init) and gives back, as `Bus.close` does, what it could not do (None when all went well).
        An Axis of a shared bus is unusable from then on; the bus runs on until closed."""
        if self._owns_bus:
            self._closed = True
            return self._bus.close()
        if self._closed or self._bus.closed:
            return None
        self._closed = True
        cycle = self._bus.cycle
        cycle.disable(self.slave)
        # A drive in Fault or unreachable stays as it is: powerless.
        with contextlib.suppress(_native.EtherCatError):
            cycle.wait_state(self.slave, _native.Ds402State.SWITCH_ON_DISABLED, timeout=1.0)
        return None

    def __enter__(self) -> Axis:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _wait_state(self, state: _native.Ds402State, timeout: float) -> None:
        """Waits for the drive to show `state`; the native time-out (which names the state it is stuck in and why)
        becomes Python's TimeoutError, as callers of a driver expect."""
        try:
            self._running().wait_state(self.slave, state, timeout=timeout)
        except _native.TimeoutError as e:
            raise TimeoutError(str(e)) from None

    def _running(self):
        if self._closed or self._bus.closed:
            raise CommandError("the axis is closed")
        return self._bus.cycle

    # --- DS402 ----------------------------------------------------------------------------------------------------

    def request(self, request: str) -> bool:
        """Asks the drive for `request` ("enable", "disable", "quick_stop", "reset_fault") and returns at once whether
        it asked: always, but for a reset of a drive that shows no fault, which is left as it is (its power stage
        untouched); `wait(request)` waits for it. The methods of the same names do both."""
        if request not in REQUESTS:
            raise CommandError(f"request {request!r} is not one of {', '.join(REQUESTS)}")
        cycle = self._running()
        if request == "enable":
            self._commanded.clear()
        return getattr(cycle, request)(self.slave) is not False

    def wait(self, request: str, timeout: float = 5.0) -> None:
        """Waits until the drive carried out `request`; TimeoutError saying in which state it is stuck and why, or
        that another request took its place (a quick stop of the whole bus after another drive's fault)."""
        try:
            if request == "quick_stop":
                done = (_native.Ds402State.QUICK_STOP_ACTIVE, _native.Ds402State.SWITCH_ON_DISABLED)
                self._wait_for(lambda s: s.state in done, "the quick stop", timeout)
            else:
                enable = request == "enable"
                self._wait_state(
                    _native.Ds402State.OPERATION_ENABLED if enable else _native.Ds402State.SWITCH_ON_DISABLED, timeout
                )
        except TimeoutError as e:
            in_force = self._running().drive_status(self.slave).request
            if in_force is not None and in_force != REQUESTS[request]:
                raise TimeoutError(f"{e}; the {request} was replaced by a {in_force} request") from None
            raise

    def enable(self, timeout: float = 5.0) -> None:
        """Brings the drive to Operation enabled and waits; the target holds the actual position until commanded.
        Raises TimeoutError saying in which state it is stuck and why (fault, hardware enable low, ...)."""
        self.request("enable")
        self.wait("enable", timeout)

    def disable(self, timeout: float = 5.0) -> None:
        """Switches the power stage off (Switch on disabled) and waits."""
        self.request("disable")
        self.wait("disable", timeout)

    def quick_stop(self, timeout: float = 5.0) -> None:
        """Brakes with the quick-stop deceleration and holds in Quick stop active (Switch on disabled if off)."""
        self.request("quick_stop")
        self.wait("quick_stop", timeout)

    def reset_fault(self, timeout: float = 5.0) -> bool:
        """Resets a fault by a rising edge of controlword bit 7 and waits for Switch on disabled; returns whether there
        was one: a drive without a fault is left as it is. Raises TimeoutError when the fault persists (its cause is
        still there)."""
        if not self.request("reset_fault"):
            return False
        self.wait("reset_fault", timeout)
        return True

    def halt(self, on: bool = True) -> None:
        """Halt (controlword bit 8): the drive stops and stays enabled; `halt(False)` lets it go on."""
        self._running().set_halt(self.slave, on)

    @property
    def mode(self) -> str:
        """The mode of operation last set."""
        return self._mode

    def set_mode(self, mode: str) -> None:
        """Changes the mode of operation. Allowed while disabled, or enabled at standstill; the target then holds the
        actual position until the first command of the new mode."""
        cycle = self._running()
        check_mode(mode)
        targets = _MODES[mode].command_objects
        # A mode started by a handshake takes its command by SDO where it is not mapped; the others need it mapped.
        if _MODES[mode].handshake_controlword is None and targets and not self._outputs.intersection(targets):
            objects = " or ".join(f"0x{i:04X}:{s:02X}" for i, s in targets)
            raise CommandError(f"mode {mode} needs {objects} in the output mapping, which this mapping lacks")
        state = self.state()
        if state.state == _native.Ds402State.OPERATION_ENABLED and state.velocity is not None:
            counts_per_s = abs(state.velocity / self.units.si_per_count)
            if counts_per_s > STANDSTILL_COUNTS_PER_S:
                raise CommandError(
                    f"mode change to {mode} refused while the axis moves ({state.velocity:.4g} "
                    f"{self.units.position_unit}/s); stop it (halt, or command zero) or disable it first"
                )
        cycle.set_mode(self.slave, MODES[mode])
        self._mode = mode
        self._commanded.clear()
        if cycle.drive_inputs(self.slave).mode_display is not None:
            self._wait_for(lambda s: s.mode_display == MODES[mode], f"the drive to show mode {mode} (0x6061)")

    def _wait_for(self, done, what: str, timeout: float = 1.0) -> None:
        """Polls the drive's status until `done(status)`; TimeoutError naming `what`, the drive's state and, for a
        request the sequencer found stuck (which ends the wait at once), why."""
        cycle = self._running()
        deadline = time.monotonic() + timeout
        while not done(status := cycle.drive_status(self.slave)):
            stuck = status.progress == _native.RequestProgress.STUCK
            if stuck or time.monotonic() > deadline:
                raise TimeoutError(
                    f"drive {self.slave}: timed out waiting for {what} (statusword 0x{status.statusword:04X}, "
                    f"state {status.state}, mode display {status.mode_display})"
                    + (f": {status.reason}" if stuck else "")
                )
            time.sleep(0.001)

    # --- commands -------------------------------------------------------------------------------------------------

    def _command(self, kind: str, value: float) -> None:
        """Sends the command through the bus (`Bus.command`) and, in profile position, waits for its set-point
        handshake: TimeoutError says why it is stuck (not in Operation enabled, statusword bit 12 not cleared or not
        set within the request time-out)."""
        self._running()
        [handshake] = self._bus.command([(self, kind, value)])
        if handshake is not None:
            self._wait_setpoint("the new position set-point")

    def _wait_setpoint(self, what: str) -> None:
        try:
            self._running().wait_setpoint(self.slave)
        except _native.TimeoutError as e:
            raise TimeoutError(f"{what}: {e}") from None

    def home(self, timeout: float = 30.0) -> None:
        """Runs the drive's homing (mode homing, with its homing method and speeds set in the drive) and waits until
        homing is attained."""
        if self._mode != "homing":
            raise CommandError(f"home() needs mode homing; the axis is in mode {self._mode} (set_mode('homing'))")
        self._running().start_setpoint(self.slave, _MODES["homing"].handshake_controlword, timeout=timeout)
        self._wait_setpoint("homing")

    def command_position(self, position: float) -> None:
        """Commands a position (rad or m) in a position mode."""
        self._command("position", position)

    def command_velocity(self, velocity: float) -> None:
        """Commands a velocity (rad/s or m/s) in profile velocity mode."""
        self._command("velocity", velocity)

    def command_torque(self, torque: float) -> None:
        """Commands a torque (N·m, or N on a linear axis) in profile torque mode."""
        self._command("torque", torque)

    def trajectory_knot(
        self, position: float, velocity: float | None = None, acceleration: float | None = None, *, point: int = 0
    ) -> tuple[int, int | None, float | None]:
        """A trajectory point of this axis (SI) in the drive's counts, counts/s and counts/s², as
        `Cycle.play_trajectory` takes it; CommandError naming the axis and `point` for NaN or a value no drive value
        carries. The cycle judges it by the axis's limits (refused whatever the limits' policy: a trajectory is not
        bent to fit)."""
        try:
            counts = self.units.position_to_counts(position)
            per_s = None if velocity is None else self.units.velocity_to_counts(velocity)
            per_s2 = None if acceleration is None else self.units.acceleration_to_counts(acceleration)
        except ValueError as e:
            raise CommandError(f"trajectory refused: joint {self.name}, point {point}: {e}") from None
        return counts, per_s, per_s2

    def position_limits_counts(self) -> tuple[float, float]:
        """The position limits in counts (low, high), a 32-bit target's range where open."""
        ends = []
        for limit in (self.limits.min_position, self.limits.max_position):
            try:
                ends.append(None if limit is None else self.units.position_to_counts(limit))
            except ValueError:
                ends.append(None)  # beyond what a 32-bit target reaches: no narrower than that
        if self.units.direction < 0:
            ends.reverse()
        low, high = ends
        return (-(2.0**31) if low is None else low, 2.0**31 - 1 if high is None else high)

    def set_command_timeout(self, seconds: float, policy: str = "hold") -> None:
        """Stops the axis in the cycle thread when a non-zero velocity (profile velocity) or torque (profile torque)
        command is not sent again within `seconds` while it is enabled: policy "hold" halts it (controlword bit 8)
        until the next command, "quick_stop" quick-stops it until `enable()`. 0 turns it off. Position commands and zero
        never time out; enable, disable, quick stop and a mode change forget the stream and lift the hold. Each
        time-out is one `CommandTimeoutEvent` (`command_timeout_events`)."""
        cycle = self._running()
        try:
            cycle.set_command_timeout(self.slave, seconds, policy)
        except _native.ConfigError as e:
            raise CommandError(str(e)) from None

    @property
    def command_kind(self) -> str | None:
        """What the mode's command sets: "position", "velocity", "torque", or None (homing)."""
        return _MODES[self._mode].command

    @property
    def command(self) -> float | None:
        """The last command accepted in the current mode (SI), None before one."""
        return self._commanded.get(_MODES[self._mode].command or "")

    # --- state and events -----------------------------------------------------------------------------------------

    def state(self, inputs=None) -> AxisState:
        """The last cycle's state of the axis; from `inputs` (this drive's `_native.DriveInputs`) where given, as
        `Bus.states` reads every drive's from one cycle."""
        cycle = self._running()
        if inputs is None:
            inputs = cycle.drive_inputs(self.slave)
        status = cycle.drive_status(self.slave)
        counts = self._unwrap.next(inputs.position_actual or 0)
        velocity, torque, following = inputs.velocity_actual, inputs.torque_actual, inputs.following_error
        mode = inputs.mode_display
        return AxisState(
            cycle=inputs.cycle,
            time_ns=inputs.time_ns,
            fresh=inputs.fresh,
            state=status.state,
            statusword=status.statusword,
            mode=MODE_NAMES.get(mode) if mode is not None else None,
            position=self.units.position_to_si(counts),
            velocity=None if velocity is None else self.units.velocity_to_si(velocity),
            torque=None if torque is None else self.units.torque_to_si(torque),
            following_error=None if following is None else following * self.units.si_per_count,
            position_counts=counts,
            request=status.request,
            progress=status.progress,
            reason=status.reason,
            digital_inputs=inputs.digital_inputs,
        )

    def io(self, io=None) -> AxisIo:
        """The drive's own I/O in the last cycle's snapshot (analog values in V); from `io` (this drive's
        `_native.DriveIo`) where given, as `Bus.io` reads every drive's from one cycle."""
        if io is None:
            io = self._running().drives_io([self.slave])[0]

        def volts(counts: int | None) -> float | None:
            return None if counts is None else counts * self.analog_scale

        return AxisIo(
            cycle=io.cycle,
            time_ns=io.time_ns,
            fresh=io.fresh,
            digital_inputs=io.digital_inputs,
            switches=dict(io.switches or ()),
            inputs=tuple(io.inputs or ()),
            hardware_enable=io.hardware_enable,
            statusword=io.statusword,
            analog_input=volts(io.analog_input),
            digital_outputs=io.digital_outputs,
            outputs=tuple(io.outputs or ()),
            analog_output=volts(io.analog_output),
        )

    def set_outputs(self, levels: dict[int, bool] | None = None, analog_output: float | None = None) -> None:
        """Sets digital outputs `levels` (output number 1..2: level) and the analog output set-point `analog_output`
        (V) in the next cycle's process image; the others stay as they are, and a held target stays held. Checked
        first, in the crate (`_native.Cycle.set_drive_outputs`): a refusal, a CommandError saying why (a mapping
        without the object, naming mappings with it; an output the AKD does not have; a voltage that is NaN or out of
        range), changes nothing."""
        cycle = self._running()
        try:
            numbered = [(int(n), bool(high)) for n, high in (levels or {}).items()]
            cycle.set_drive_outputs(self.slave, self.name, numbered, analog_output, self.analog_scale)
        except (_native.ConfigError, TypeError, ValueError) as e:
            message = str(e)
            raise CommandError(message if "refused" in message else f"outputs refused: {message}") from None

    def recovery(self) -> dict:
        """Where the recovery of this drive stands (`_native.Cycle.recovery_status`): "recovering" while it is lost and
        being brought back, "attempts", "recoveries" and "last_error"."""
        return self._running().recovery_status(self.slave)

    def arm_latch(self, channel: int, edge: str, arm: bool = True) -> None:
        """Arms latch `channel` (1 or 2) on `edge` ("rising" or "falling"); every capture becomes a LatchEvent."""
        self._running().arm_latch(self.slave, channel, edge, arm)

    def _poll(self) -> None:
        if self._closed or self._bus.closed:
            return
        events = list(self._bus.events_of(self.slave))
        inputs = [e for e in events if e["kind"] == "inputs"]
        if inputs:
            # The outputs and the analog input of a change are the last snapshot's: only 0x60FD is the event's.
            now = self._running().drives_io([self.slave])[0]
            for e in inputs:
                self._input_events.append(
                    self.io(now.with_inputs(e["cycle"], e["time_ns"], e["digital_inputs"], e["statusword"]))
                )
        for e in events:
            if e["kind"] == "inputs":
                continue
            if e["kind"] == "latch":
                counts = e["position"]
                self._latches.append(
                    LatchEvent(
                        e["cycle"], e["time_ns"], e["channel"], e["edge"], self.units.position_to_si(counts), counts
                    )
                )
            elif e["kind"] == "command_timeout":
                to_si = self.units.velocity_to_si if e["command"] == "velocity" else self.units.torque_to_si
                self._command_timeouts.append(
                    CommandTimeoutEvent(
                        e["cycle"],
                        e["time_ns"],
                        e["command"],
                        e["timeout"],
                        to_si(e["value"]),
                        e["value"],
                        e["statusword"],
                        e["ds402_state"],
                        e["action"],
                        e["text"],
                    )
                )
            else:
                self._faults.append(e["fault"])

    def latch_events(self) -> Iterator[LatchEvent]:
        """The latch captures since the last call, oldest first, each handed out once."""
        self._poll()
        while self._latches:
            yield self._latches.popleft()

    def fault_events(self) -> Iterator[FaultEvent]:
        """The faults since the last call, oldest first, each handed out once."""
        self._poll()
        while self._faults:
            yield self._faults.popleft()

    def input_events(self) -> Iterator[AxisIo]:
        """Each change of the drive's digital inputs (0x60FD) or hardware enable since the last call, oldest first, each
        handed out once: the I/O of the cycle whose inputs showed it (its outputs and analog input those of the
        snapshot when it was taken). The last INPUT_EVENTS_KEPT are kept between calls."""
        self._poll()
        while self._input_events:
            yield self._input_events.popleft()

    def command_timeout_events(self) -> Iterator[CommandTimeoutEvent]:
        """The command time-outs since the last call, oldest first, each handed out once."""
        self._poll()
        while self._command_timeouts:
            yield self._command_timeouts.popleft()

    def samples(self) -> dict[str, list]:
        """Every cycle's record of this drive since the last call, as columns in drive units (see
        `_native.Cycle.samples`); `units` converts them. For recording: take them at least every few seconds."""
        self._running()
        return self._bus.samples_of(self.slave)

    # --- mailbox and statistics -----------------------------------------------------------------------------------

    def sdo_read(self, index: int, subindex: int = 0) -> bytes:
        """Reads an object of the drive beside the running cycle."""
        return self._running().sdo_read(self.slave, index, subindex)

    def sdo_write(self, index: int, subindex: int, data: bytes) -> None:
        """Writes an object of the drive beside the running cycle."""
        self._running().sdo_write(self.slave, index, subindex, data)

    def stats(self) -> dict:
        """The cycle thread's statistics (see `_native.Cycle.stats`), plus events dropped: those of the whole bus."""
        self._running()
        return self._bus.stats()

    @property
    def cycle(self):
        """The native cycle, for what the Axis does not wrap (histograms, raw snapshots)."""
        return self._running()
