"""`Bus`: one EtherCAT line of AKDs from Python, without ROS: the one master and the one cycle thread.

The line may hold other slaves beside the drives (an EK1100 coupler, EL1xxx inputs, EL2xxx outputs): the master
configures each from what it says of itself and takes it to Op with the drives. Those named in `devices`
(`akd_ros.device.DeviceConfig`) are the Bus's `devices` (`akd_ros.device.Device`), read and set by channel name.

A Bus opens a link (``"sim"``/``"sim:N"`` for built-in virtual AKDs, ``"udp://HOST:PORT"`` for `akd-sim`, or a
network interface), scans it, picks its drives by position or station alias, gives each its process-data mapping and
mode of operation in PreOp, takes the line to Op and starts one native cycle for all of them. Each drive is commanded
through its `akd_ros.Axis` (`bus.axes`, `bus["name"]`), with its own units, limits, mode, latches and events; the Bus
takes the cycle's events and per-cycle records and hands each to the Axis of its drive, once.

With ``fault_reaction="all"`` (the default, as an arm needs) a drive entering Fault or leaving Op quick-stops every
other drive in the same cycle: the cycle thread sees the fault first and asks for the quick stops there, so they do
not wait for Python to poll. ``"joint"`` leaves the others as they are.

`enable`, `disable`, `quick_stop` and `reset_fault` ask every drive at once and wait for all; a `BusRequestError`
names each drive that did not get there and why.

Distributed clocks (`dc`), set once for the whole line in PreOp: on, every drive's PLL follows SYNC0 at the period
(moved by `dc_shift` seconds); off, it follows each frame's SM2 event. By default (None) they are on for a network
interface and off for the virtual AKDs and UDP, whose frames' timing is not a wire's (`_native.dc_by_default`);
`bus.cycle.dc_status()` tells what runs, and which drives' FBUS.PARAM02 could not be confirmed and was left alone.
"""

from __future__ import annotations

import contextlib
import ipaddress
import math
import threading
import time
from collections.abc import Iterator, Sequence

from akd_ros import _native

_MODES = {mode.name: mode for mode in _native.MODES_OF_OPERATION}
MODES: dict[str, int] = {name: mode.code for name, mode in _MODES.items()}
"""The CiA 402 modes the AKD offers over EtherCAT, by name, with their codes (from the extension's table,
`_native.MODES_OF_OPERATION`, which also gives each mode's command, the objects it is written to and the handshake
that starts it)."""

FAULT_REACTIONS = ("all", "joint")
"""What a fault on one drive does to the others: "all" quick-stops them, "joint" leaves them."""

REQUESTS = {str(request): request for request in _native.DRIVE_REQUESTS}
"""The requests a Bus makes of every drive at once, by name ("enable", "disable", "quick_stop", "reset_fault"): the
crate's `DriveRequest`s, as `Cycle.drive_status` reports them."""

SAMPLES_KEPT = _native.SAMPLES_PER_DRIVE
"""Per-cycle records a Bus keeps for each drive until they are taken (as many as the cycle's own ring holds for each
drive)."""


class CommandError(ValueError):
    """A command or request was refused before anything reached the drive; of a command of several axes
    (`Bus.command`), `joint` names the axis whose command was refused."""

    def __init__(self, message: str, joint: str | None = None) -> None:
        super().__init__(message)
        self.joint = joint


class BusRequestError(TimeoutError):
    """A request to every drive that some did not carry out: `failed` maps each such drive's name to why,
    `done` lists the others."""

    def __init__(self, request: str, failed: dict[str, str], done: list[str]) -> None:
        self.request, self.failed, self.done = request, failed, done
        why = "; ".join(f"{name}: {reason}" for name, reason in failed.items())
        super().__init__(
            f"{request}: {len(failed)} of {len(failed) + len(done)} drives refused ({why}); done: "
            f"{', '.join(done) or 'none'}"
        )


def _no_samples() -> dict[str, list]:
    """`_native.Cycle.samples`' columns, empty."""
    return {name: [] for name in _native.SAMPLE_COLUMNS}


def check_mode(mode: str) -> None:
    """CommandError unless `mode` is one of the AKD's modes; for CiA 402's cyclic synchronous velocity and torque, it
    says why the AKD has none and which of its modes does that."""
    if mode not in MODES:
        why = _native.MODES_NOT_OFFERED.get(mode)
        raise CommandError(f"mode {mode!r} is not one of {', '.join(MODES)}" + (f": {why}" if why else ""))


def _picked(drives: Sequence, master, slaves: list[dict]) -> list[int]:
    """The bus position of each drive (by `slave` or, through the master, `alias`) among the `slaves` its scan found,
    or CommandError naming what is wrong."""
    positions = []
    for drive in drives:
        if drive.alias is not None:
            try:
                position = master.position_of_alias(drive.alias)
            except _native.ConfigError as e:
                aliases = ", ".join(f"{s['position']}: {s['alias']}" for s in slaves)
                raise CommandError(f"{e} (position: alias of each: {aliases})") from None
        else:
            position = drive.slave
        if not 0 <= position < len(slaves):
            raise CommandError(
                f"slave {position} is not on the bus: the line has {len(slaves)} slaves (0..{len(slaves) - 1}); "
                f"drive {drive.name or len(positions)} expects an AKD there"
            )
        if position in positions:
            raise CommandError(
                f"slave {position} is given twice (drives {positions.index(position)} and "
                f"{len(positions)}); each drive once"
            )
        positions.append(position)
    return positions


def check(drives: Sequence, fault_reaction: str, period: float, dc_shift: float, devices: Sequence = ()) -> None:
    """CommandError for what can be told wrong of a Bus's settings before the bus is touched."""
    if not all(math.isfinite(x) for x in (period, dc_shift)):
        raise CommandError(f"period and dc_shift must be finite seconds, got {period!r} and {dc_shift!r}")
    if fault_reaction not in FAULT_REACTIONS:
        raise CommandError(f"fault_reaction {fault_reaction!r} is not one of {', '.join(FAULT_REACTIONS)}")
    if not drives:
        raise CommandError("a bus needs at least one drive")
    for key in ("slave", "alias", "name"):
        given = [getattr(d, key) for d in drives if getattr(d, key) is not None]
        twice = sorted({v for v in given if given.count(v) > 1}, key=str)
        if twice:
            raise CommandError(f"{key} {', '.join(map(str, twice))} given to several drives; each drive once")
    for i, d in enumerate(drives):
        if (d.slave is None) == (d.alias is None):
            which = "both given" if d.slave is not None else "neither given"
            raise CommandError(
                f"drive {i}{f' ({d.name})' if d.name else ''}: give its slave (position on the bus) or its alias, "
                f"one of them ({which})"
            )
        check_mode(d.mode)
    drive_slaves = {d.slave for d in drives if d.slave is not None}
    drive_names = {d.name for d in drives if d.name is not None}
    for key in ("slave", "name"):
        given = [getattr(d, key) for d in devices if getattr(d, key) is not None]
        twice = sorted({v for v in given if given.count(v) > 1}, key=str)
        if twice:
            raise CommandError(f"{key} {', '.join(map(str, twice))} given to several devices; each device once")
    for d in devices:
        if d.slave in drive_slaves:
            raise CommandError(
                f"slave {d.slave} is given to a drive and to device {d.name or d.slave}; each slave once"
            )
        if d.name is not None and d.name in drive_names:
            raise CommandError(f"name {d.name} is given to a drive and to a device; each name once")


def _a(product: str) -> str:
    """`product` with its article: "an EL2004", "an AKD", "a BK1120"."""
    return f"{'an' if product[:1].upper() in 'AEFHILMNORSX' else 'a'} {product}"


def product_of(slave: dict) -> str:
    """What a slave `Master.scan` found is, in a word: "AKD" for an AKD, else its order number as its SII gives it
    (e.g. "EL2004"), else its product code."""
    if slave.get("akd"):
        return "AKD"
    return slave.get("order") or f"product 0x{slave['product_code']:08X} of vendor 0x{slave['vendor_id']:08X}"


def check_line(slaves: list[dict], drives: dict[str, int], devices: Sequence) -> None:
    """CommandError, in one line, for the first difference between the line `slaves` (`Master.scan`) and what the Bus
    expects of it: each drive (by name: its position) an AKD, each device (`DeviceConfig`) at a position the line has,
    no AKD, and the product it names where it names one."""
    for name, position in drives.items():
        if not slaves[position].get("akd"):
            raise CommandError(f"slave {position} is {_a(product_of(slaves[position]))}; drive {name} expects an AKD")
    for d in devices:
        who = f"device {d.name or d.slave}"
        if not 0 <= d.slave < len(slaves):
            raise CommandError(
                f"slave {d.slave} is not on the bus: the line has {len(slaves)} slaves (0..{len(slaves) - 1}); {who} "
                f"expects {_a(d.product) if d.product else 'a device'} there"
            )
        found = product_of(slaves[d.slave])
        if found == "AKD":
            raise CommandError(f"slave {d.slave} is an AKD; {who} expects a device beside the drives: make it a drive")
        if d.product is not None and found.lower() != d.product.lower():
            raise CommandError(f"slave {d.slave} is {_a(found)}; {who} expects {_a(d.product)}")


class Bus:
    """One EtherCAT line: its master, its one cycle thread, an `Axis` per drive and a `Device` per device.

    `drives` are `akd_ros.DriveConfig`s, one per drive to command; `devices` `akd_ros.device.DeviceConfig`s, one per
    other slave to read and set by name (a terminal); the line is checked against both before anything goes to Op
    (a drive where the line has no AKD, a device where it has none or another product: one CommandError);
    `realtime` (an `akd_ros.RealTime`, the same options as an Axis's and the node's `rt.*` parameters) how the cycle
    thread runs; `line_reads` whether it reads every slave's links and error counters beside the cycle
    (`line_health`; a frame a few times a second). Use as a context manager or call
    `close()`: it disables every drive, stops the cycle and returns the line to Init.
    """

    def __init__(
        self,
        link: str = "sim",
        drives: Sequence = (),
        *,
        period: float = 0.001,
        realtime: _native.RealTime | None = None,
        request_timeout: float = 1.0,
        frame_timeout: float = 0.1,
        fault_reaction: str = "all",
        dc: bool | None = None,
        dc_shift: float = 0.0,
        line_reads: bool = True,
        devices: Sequence = (),
    ) -> None:
        check(drives, fault_reaction, period, dc_shift, devices)
        self.link = link
        self.fault_reaction = fault_reaction
        self._master = _native.Master(link, timeout=frame_timeout)
        self._cycle = None
        try:
            self.slaves: list[dict] = self._master.scan()
            """What the scan found of each slave on the line (`_native.Master.scan`), by position: identity (vendor,
            product, revision, serial number), name, model, firmware, station alias."""
            positions = _picked(drives, self._master, self.slaves)
            named = {d.name or f"slave_{p}": p for d, p in zip(drives, positions, strict=True)}
            check_line(self.slaves, named, devices)
            self.unnamed: list[int] = sorted(set(range(len(self.slaves))) - set(positions) - {d.slave for d in devices})
            """The positions of the slaves neither a drive nor a device: they go to Op with the others, their outputs
            off."""
            self.simulator = None
            """For built-in virtual AKDs: their `Simulator` (fault injection, hardware enable, input toggles)."""
            # The extension knows which links are virtual: the others have no simulator.
            with contextlib.suppress(_native.ConfigError):
                self.simulator = self._master.simulator
            self._master.request_state("preop")
            self.eoe_drives: dict[bytes, int] = {}
            """The MAC of each drive given an `eoe_ip`, with its position: where an `EoeBridge` sends frames."""
            self.scalings: dict[int, _native.PositionScaling | None] = {}
            """Each drive's position scaling as its DS402 scaling objects give it (`_native.Master.position_scaling`,
            read in PreOp), by position; its Axis checks its units against it."""
            for drive, position in zip(drives, positions, strict=True):
                if drive.eoe_ip is not None:
                    address = ipaddress.IPv4Interface(drive.eoe_ip)
                    mac = self._master.eoe_set_ip(position, str(address.ip), subnet_mask=str(address.netmask))
                    self.eoe_drives[bytes.fromhex(mac.replace(":", ""))] = position
                rx, tx = drive.mapping if drive.mapping is not None else _native.DEFAULT_MAPPING
                self._master.configure_pdo(position, rx, tx)
                self.scalings[position] = self._master.position_scaling(position)
                self._master.set_mode(position, MODES[drive.mode])
            # One clock set-up for the line: every drive with DC follows the same SYNC0 (or each its SM2 event).
            if _native.dc_by_default(link) if dc is None else dc:
                self._master.configure_dc(round(period * 1e9), round(dc_shift * 1e9))
            else:
                self._master.configure_sm2_sync(round(period * 1e9))
            self._master.request_state("op")
            # The cycle's own interval for the line's reads, or none (line_health 0).
            interval = {} if line_reads else {"line_health": 0}
            self._cycle = _native.Cycle(self._master, period, realtime=realtime, **interval)
        except BaseException:
            self._master.close()
            raise
        self._cycle.request_timeout = request_timeout
        self._cycle.set_quick_stop_on_fault(fault_reaction == "all")
        self._poll_lock = threading.Lock()
        self._events: dict[int, list[dict]] = {p: [] for p in [*positions, *(d.slave for d in devices)]}
        self._trajectory_events: list[dict] = []
        self._samples: dict[int, dict[str, list]] = {p: _no_samples() for p in positions}
        self._samples_dropped = dict.fromkeys(positions, 0)
        self.axes = []
        """One `Axis` per drive, in the order given."""
        self.devices = []
        """One `akd_ros.device.Device` per device, in the order given."""
        try:
            self.axes.extend(d.attach(self, p) for d, p in zip(drives, positions, strict=True))
            self.devices.extend(d.attach(self, d.slave) for d in devices)
        except BaseException:
            self.close()
            raise

    # --- life cycle ---------------------------------------------------------------------------------------------

    @property
    def cycle(self):
        """The native cycle, for what the Bus and its axes do not wrap (histograms, raw snapshots)."""
        if self._cycle is None:
            raise CommandError("the bus is closed")
        return self._cycle

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""
        return self._cycle is None

    @property
    def warnings(self) -> list[str]:
        """What was asked for and not permitted, one sentence each: the threads that kept their capabilities after
        the raw socket was open (`_native.Master.warnings`), real-time settings of the cycle."""
        return [*self._master.warnings, *self.cycle.warnings]

    def close(self) -> str | None:
        """Disables every drive (waiting up to a second), stops the cycle and returns the line to Init. What it could
        not do (a line that is gone: the drives are then left to their own reaction, F125 on an AKD) is given back as
        one sentence rather than raised, so that closing always ends; None when all went well."""
        if self._cycle is None:
            return None
        cycle = self._cycle
        problem = None
        try:
            if cycle.running:
                for device in self.devices:
                    with contextlib.suppress(_native.EtherCatError):
                        cycle.switch_outputs_off(device.slave)
                for axis in self.axes:
                    cycle.disable(axis.slave)
                deadline = time.monotonic() + 1.0
                for axis in self.axes:
                    # A drive in Fault or unreachable stays as it is: powerless.
                    with contextlib.suppress(_native.EtherCatError):
                        cycle.wait_state(
                            axis.slave,
                            _native.Ds402State.SWITCH_ON_DISABLED,
                            timeout=max(deadline - time.monotonic(), 0),
                        )
                # The devices' outputs off go out in a cycle before the line leaves Op.
                sent = cycle.snapshot()["cycle"] + 2
                while self.devices and cycle.snapshot()["cycle"] < sent and time.monotonic() < deadline:
                    time.sleep(cycle.period)
        finally:
            self._cycle = None
            cycle.stop()
            try:
                self._master.request_state("init")
            except _native.EtherCatError as e:
                problem = f"the line did not go back to Init ({e}); the drives are left to their own reaction"
            finally:
                self._master.close()
        return problem

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def names(self) -> list[str]:
        """The axes' names, in order."""
        return [axis.name for axis in self.axes]

    def device(self, name: str):
        """The Device named `name`."""
        for device in self.devices:
            if device.name == name:
                return device
        raise KeyError(f"no device named {name!r} on this bus (devices: {', '.join(d.name for d in self.devices)})")

    def devices_io(self) -> dict:
        """Every device's channels (`Device.io`) by name, all of the same cycle."""
        ios = self.cycle.devices_io([device.slave for device in self.devices])
        return {device.name: device.io(i) for device, i in zip(self.devices, ios, strict=True)}

    def __getitem__(self, name: str):
        """The Axis named `name`."""
        for axis in self.axes:
            if axis.name == name:
                return axis
        raise KeyError(f"no axis named {name!r} on this bus (axes: {', '.join(a.name for a in self.axes)})")

    # --- every drive at once --------------------------------------------------------------------------------------

    def _every(self, request: str, timeout: float) -> list[str]:
        """Asks every drive for `request` and waits; gives the names of those it was not asked of (a reset of a drive
        without a fault)."""
        self.cycle  # noqa: B018  (a closed bus refuses before any drive is asked)
        refusals = (TimeoutError, ValueError, _native.EtherCatError)
        failed, asked, done, untouched = {}, [], [], []
        for axis in self.axes:
            try:
                (asked if axis.request(request) else untouched).append(axis)
            except refusals as e:
                failed[axis.name] = str(e)
        deadline = time.monotonic() + timeout
        for axis in asked:
            try:
                axis.wait(request, max(deadline - time.monotonic(), 0.0))
                done.append(axis.name)
            except refusals as e:
                failed[axis.name] = str(e)
        if failed:
            raise BusRequestError(request, {a.name: failed[a.name] for a in self.axes if a.name in failed}, done)
        return [axis.name for axis in untouched]

    def enable(self, timeout: float = 5.0) -> None:
        """Brings every drive to Operation enabled together; each target holds its actual position until commanded."""
        self._every("enable", timeout)

    def disable(self, timeout: float = 5.0) -> None:
        """Switches every drive's power stage off (Switch on disabled)."""
        self._every("disable", timeout)

    def quick_stop(self, timeout: float = 5.0) -> None:
        """Quick-stops every drive (Quick stop active, Switch on disabled where off)."""
        self._every("quick_stop", timeout)

    def reset_fault(self, timeout: float = 5.0) -> list[str]:
        """Resets the fault of every drive that shows one, to Switch on disabled; the others are left as they are
        (their power stages untouched). Gives the names of the drives reset."""
        untouched = self._every("reset_fault", timeout)
        return [name for name in self.names if name not in untouched]

    # --- what the cycle reports, filed under each drive -------------------------------------------------------------

    def events_of(self, slave: int) -> Iterator[dict]:
        """The cycle's events (`_native.Cycle.events`) of drive `slave` since the last call, oldest first, each once;
        those of slaves that are not the bus's drives are dropped."""
        with self._poll_lock:
            self._take_events()
            taken, self._events[slave] = self._events[slave], []
        yield from taken

    def trajectory_events(self) -> Iterator[dict]:
        """The cycle's trajectory events (a trajectory started, done, replaced or aborted; see
        `_native.Cycle.events`) since the last call, oldest first, each once."""
        with self._poll_lock:
            self._take_events()
            taken, self._trajectory_events = self._trajectory_events, []
        yield from taken

    def events_waiting(self) -> bool:
        """Whether the cycle has events waiting, or some were filed under a drive (taken with another's, e.g. with
        `trajectory_events`) and not handed out yet; cheap enough to ask at every publication."""
        if self._cycle is None:
            return False
        return self._cycle.events_pending or any(self._events.values())

    def _take_events(self) -> None:
        if self._cycle is None:
            return
        for e in self._cycle.events():
            if e["kind"] == "trajectory":
                self._trajectory_events.append(e)
            elif e["slave"] in self._events:
                self._events[e["slave"]].append(e)

    # --- commands -----------------------------------------------------------------------------------------------------

    def command(self, commands: Sequence[tuple]) -> list[int | None]:
        """Commands axes in SI units, each of `commands` an (axis, kind, value) with kind "position", "velocity" or
        "torque": each value clamped or refused by its axis's `Limits`, then, in one call to the crate
        (`_native.Cycle.command`), checked against its drive's mode, converted by its `Units`, encoded for the target
        object its mode and mapping give, and written into the next cycle's outputs (by SDO where a profile-position
        target is unmapped). All are checked before any is sent; CommandError says why not, naming the axis in
        `joint`. A profile-position command starts its set-point handshake in the cycle thread and returns at once:
        each command's handshake number (None in a mode without one), whose outcome `cycle.setpoint_status(slave)`
        gives."""
        cycle = self.cycle
        checked = []
        for axis, kind, value in commands:
            try:
                checked.append((axis, kind, axis.limits.check(kind, value)))
            except ValueError as e:
                raise CommandError(f"{kind} command refused: {e}", joint=axis.name) from None
        try:
            handshakes = cycle.command([(axis.slave, kind, value, axis.units) for axis, kind, value in checked])
        except _native.ConfigError as e:
            refused = checked[e.command][0].name if getattr(e, "command", None) is not None else None
            raise CommandError(str(e), joint=refused) from None
        for axis, kind, value in checked:
            axis._commanded[kind] = value
        return handshakes

    # --- trajectories -----------------------------------------------------------------------------------------------

    def play_trajectory(
        self,
        joints: Sequence[str],
        times: Sequence[float],
        points: Sequence[Sequence[tuple[float, float | None, float | None]]],
        start_ns: int | None = None,
        tolerances: Sequence[tuple[float, float, float, float, float]] | None = None,
        goal_time: float = 0.0,
    ) -> int:
        """Plays a trajectory in the cycle thread: axis `joints[j]` through `points[k][j]` = (position, velocity or
        None, acceleration or None) in SI units at `times[k]` seconds from the start (strictly increasing, the first
        > 0), from `start_ns` (time.monotonic_ns(); None: now); quintic where accelerations are given, cubic where
        velocities are, linear otherwise. Each axis must be enabled in interpolated or cyclic synchronous position,
        and not being homed. It takes over from the trajectory in force without a step. CommandError, before
        anything moves, for an unknown joint, a point or the path between points past an axis's limits (position,
        max_velocity, max_acceleration: always refused, whatever the policy), NaN or bad times; the cycle judges it
        again when it takes over, where it may end "refused", nothing moved.
        With `tolerances` (per joint: path position, path velocity, goal position, goal velocity in SI, inf where not
        judged, and the stop deceleration in SI/s²) and `goal_time` (s), the cycle thread judges it as
        FollowJointTrajectory does and `cycle.stop_trajectory` brakes it. Returns its id (see
        `cycle.trajectory_status` and `trajectory_events`)."""
        axes = [self[name] for name in joints] if all(n in self.names for n in joints) else None
        if axes is None:
            unknown = [n for n in joints if n not in self.names]
            raise CommandError(
                f"trajectory refused: unknown joint {', '.join(unknown)} (joints: {', '.join(self.names)})"
            )
        if len(set(joints)) != len(joints):
            raise CommandError(f"trajectory refused: a joint is named twice in {', '.join(joints)}")
        times_ns = []
        for k, t in enumerate(times):
            if not math.isfinite(t) or t < 0:
                raise CommandError(
                    f"trajectory refused: point {k}'s time from the start is {t} s; times are finite, increasing "
                    "seconds after the start (the first > 0)"
                )
            times_ns.append(round(t * 1e9))
        if not math.isfinite(goal_time) or goal_time < 0:
            raise CommandError(f"trajectory refused: goal time {goal_time} s; allowed a finite number of seconds >= 0")
        knots = []
        for k, point in enumerate(points):
            if len(point) != len(axes):
                raise CommandError(f"trajectory refused: point {k} has {len(point)} values for {len(axes)} joints")
            knots.append([axis.trajectory_knot(*knot, point=k) for axis, knot in zip(axes, point, strict=True)])
        counted = None
        if tolerances is not None:
            # Magnitudes: counts per SI unit, whatever the direction.
            counted = [
                tuple(abs(value / axis.units.si_per_count) for value in tolerance)
                for axis, tolerance in zip(axes, tolerances, strict=True)
            ]
        try:
            return self.cycle.play_trajectory(
                [a.slave for a in axes], times_ns, knots, start_ns, counted, round(goal_time * 1e9), names=list(joints)
            )
        except (_native.ConfigError, OverflowError) as e:
            # The crate's refusal says "trajectory refused, nothing moved: " and why.
            raise CommandError(str(e)) from None

    def samples_of(self, slave: int) -> dict[str, list]:
        """Every cycle's record of drive `slave` since the last call (see `_native.Cycle.samples`), each once."""
        with self._poll_lock:
            by_slave = self.cycle.samples(by_slave=True)
            for position, kept in self._samples.items():
                for name, values in by_slave.get(position, {}).items():
                    kept[name].extend(values)
                excess = len(kept["slave"]) - SAMPLES_KEPT
                if excess > 0:
                    for values in kept.values():
                        del values[:excess]
                    self._samples_dropped[position] += excess
            taken, self._samples[slave] = self._samples[slave], _no_samples()
        return taken

    def samples(self) -> dict[str, list]:
        """Every drive's records since they were last taken, as `samples_of` gives them, in cycle order."""
        per_drive = [self.samples_of(axis.slave) for axis in self.axes]
        order = sorted((cycle, k, i) for k, columns in enumerate(per_drive) for i, cycle in enumerate(columns["cycle"]))
        return {name: [per_drive[k][name][i] for _, k, i in order] for name in per_drive[0]}

    def samples_dropped(self, slave: int) -> int:
        """Records of drive `slave` dropped because they were not taken in time (beyond the cycle's own
        `samples_dropped`)."""
        return self._samples_dropped[slave]

    def states(self) -> dict:
        """Every axis's state (`Axis.state`) by name, the drives' values all of the same cycle."""
        inputs = self.cycle.drives_inputs([axis.slave for axis in self.axes])
        return {axis.name: axis.state(i) for axis, i in zip(self.axes, inputs, strict=True)}

    def io(self) -> dict:
        """Every axis's own I/O (`Axis.io`) by name, the drives' values all of the same cycle."""
        ios = self.cycle.drives_io([axis.slave for axis in self.axes])
        return {axis.name: axis.io(i) for axis, i in zip(self.axes, ios, strict=True)}

    def slave_names(self) -> dict[int, str]:
        """Each commanded drive's position and its axis's name: how the line's words name the slaves."""
        return {axis.slave: axis.name for axis in self.axes}

    def line_health(self) -> dict:
        """Every slave's links and error counters as the reads beside the cycle found them (`_native.Cycle.line_health`:
        each port's link, what is at its other end, its counters since the start and over the last 10 s, and the
        findings in the cable's words), the drives named by their axes' names, the other slaves by their product."""
        return self.cycle.line_health(self.slave_names())

    def line_diagnostics(self) -> list[tuple]:
        """What /diagnostics says of the line (`_native.Cycle.line_diagnostics`): a status of the line and one per
        slave, each (level, what, message, hardware_id, [(key, value)]), named as `line_health` names them."""
        return self.cycle.line_diagnostics(self.link, self.slave_names())

    def stats(self) -> dict:
        """The cycle thread's statistics (see `_native.Cycle.stats`), plus events dropped and per-cycle records dropped
        (by the cycle's ring or here) because they were not taken in time."""
        cycle = self.cycle
        stats = cycle.stats()
        stats["events_dropped"] = cycle.events_dropped
        stats["samples_dropped"] = cycle.samples_dropped + sum(self._samples_dropped.values())
        return stats
