"""Joint trajectories interpolated in the cycle thread (Cycle.play_trajectory) on three virtual
AKDs of Master("sim:3"), through the real Master and Cycle.

Drive 0 is in interpolated position and drive 1 in cyclic synchronous position with akd_ros's
default mapping; drive 2 in cyclic synchronous position with the fixed 0x1724/0x1B24 (0x607A
only, no mode display). The trajectories here are linear (positions only), so the velocity the
cycle thread interpolates at any instant is the slope between two points, computed here from
the points alone: each cycle's step in the per-cycle records (Cycle.samples()) must stay within
it times the time between the two cycles, plus one count. The waits have deadlines only so
that a failure does not hang.

A host loaded beyond its cores can stall the cycle thread for more than seven cycles, which
would fault real drives with F125 (synchronization lost) and end a trajectory for a reason
that is not the one under test: the virtual AKDs here judge missed frames by the frames the
line lost (`?missed=lost`), not by this shared host's scheduling.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import time

import pytest
from akd_ros._native import Ds402State

from akd_ros import _native

DRIVES = [0, 1, 2]
S = 1_000_000_000
# Where the axis must settle on a trajectory's last point, counts.
SETTLED = 20


@contextlib.contextmanager
def rig():
    """The enabled Cycle of the three drives and the Simulator that controls them."""
    rx, tx = _native.DEFAULT_MAPPING
    setups = [((rx, tx), 7), ((rx, tx), 8), ((0x1724, 0x1B24), 8)]
    with _native.Master("sim:3?missed=lost") as m:
        m.scan()
        m.request_state("preop")
        for slave, ((out, inp), mode) in enumerate(setups):
            m.configure_pdo(slave, out, inp)
            m.sdo_write(slave, 0x6060, 0, bytes([mode]))
        m.request_state("op")
        simulator = m.simulator
        with _native.Cycle(m, 0.001) as c:
            for slave in DRIVES:
                c.enable(slave)
            for slave in DRIVES:
                c.wait_state(slave, Ds402State.OPERATION_ENABLED)
            yield c, simulator


def on_the_rig(scenario) -> None:
    """Runs `scenario(cycle, simulator, records)` on a fresh rig."""
    with rig() as (cycle, simulator):
        scenario(cycle, simulator, Records(cycle))


class Records:
    """The per-cycle records, drained as they come, per drive."""

    def __init__(self, cycle):
        self.cycle = cycle
        self.columns: dict[str, list] = {}
        self.events: list[dict] = []

    def take(self) -> None:
        for name, values in self.cycle.samples().items():
            self.columns.setdefault(name, []).extend(values)
        self.events.extend(self.cycle.events())

    def trajectory_events(self) -> list[dict]:
        self.take()
        return [e for e in self.events if e["kind"] == "trajectory"]

    def wait(self, cycles: int) -> None:
        start = self.cycle.snapshot()["cycle"]
        deadline = time.monotonic() + 30
        while self.cycle.snapshot()["cycle"] < start + cycles:
            assert time.monotonic() < deadline, "the cycle stopped"
            self.take()
            time.sleep(0.02)
        self.take()

    def until_ended(self, trajectory: int) -> dict:
        deadline = time.monotonic() + 30
        while (status := self.cycle.trajectory_status(trajectory))["state"] in ("pending", "running"):
            assert time.monotonic() < deadline, status
            self.take()
            time.sleep(0.02)
        self.take()
        return status

    def of(self, slave: int, name: str, since_cycle: int = 0) -> list:
        c = self.columns
        return [v for s, n, v in zip(c["slave"], c["cycle"], c[name], strict=True) if s == slave and n >= since_cycle]

    def last_targets(self) -> list[int]:
        return [self.of(d, "target_position")[-1] for d in DRIVES]


def linear_position(knots: list[tuple[int, float]], t_ns: int) -> float:
    """The linear interpolation of `knots` (time ns, position) at `t_ns`, held after the last."""
    for (t0, p0), (t1, p1) in itertools.pairwise(knots):
        if t0 <= t_ns < t1:
            return p0 + (p1 - p0) * (t_ns - t0) / (t1 - t0)
    return knots[-1][1] if t_ns >= knots[-1][0] else knots[0][1]


def slope(knots: list[tuple[int, float]], t_ns: int) -> float:
    """|velocity| of the linear interpolation of `knots` at `t_ns`, counts/s (0 outside)."""
    for (t0, p0), (t1, p1) in itertools.pairwise(knots):
        if t0 <= t_ns < t1:
            return abs(p1 - p0) / ((t1 - t0) * 1e-9)
    return 0.0


def assert_continuous(records: Records, slave: int, knots: list[tuple[int, float]]) -> None:
    """Each step of drive `slave`'s target within the interpolated velocity (the largest of the
    two instants' slopes) times the time between the cycles, plus one count."""
    times, targets = records.of(slave, "time_ns"), records.of(slave, "target_position")
    steps = zip(times, targets, strict=True)
    for (t0, p0), (t1, p1) in zip(steps, zip(times[1:], targets[1:], strict=True), strict=False):
        velocity = max(slope(knots, t0), slope(knots, t1))
        allowed = velocity * (t1 - t0) * 1e-9 + 1
        assert abs(p1 - p0) <= allowed, f"drive {slave}: step {p1 - p0} > {allowed:.1f} at {t1}"


def three_points(base: list[int]) -> tuple[list[int], list[list[float]]]:
    """Three points over 2 s from `base`: out, further, back past the start."""
    times = [S // 2, 6 * S // 5, 2 * S]
    offsets = [100_000, 150_000, -50_000]
    return times, [[b + o for b in base] for o in offsets]


def knots_of(status: dict, times: list[int], points: list[list[float]], joint: int, start: float):
    """Joint `joint`'s knots on the monotonic clock: the start, then the points."""
    t0 = status["started_ns"]
    return [(t0, start)] + [(t0 + t, p[joint]) for t, p in zip(times, points, strict=True)]


def play_three_points(cycle, records: Records, start_ns: int | None = None):
    """Plays `three_points` from where the drives are: their targets, the times, the points and
    the trajectory's id."""
    records.wait(20)
    base = records.last_targets()
    times, points = three_points(base)
    return base, times, points, cycle.play_trajectory(DRIVES, times, points, start_ns=start_ns)


def test_a_three_point_trajectory_is_followed_continuously_and_ends_on_its_last_point():
    on_the_rig(followed)


def followed(cycle, _simulator, records):
    base, times, points, trajectory = play_three_points(cycle, records)
    status = records.until_ended(trajectory)
    assert (status["state"], status["point"], status["points"]) == ("done", 3, 3), status
    assert status["elapsed_ns"] >= status["duration_ns"] == 2 * S
    records.wait(300)
    for joint, drive in enumerate(DRIVES):
        assert_continuous(records, drive, knots_of(status, times, points, joint, base[joint]))
        targets = records.of(drive, "target_position")
        # The cycle nearest the middle point comes within a cycle's motion of it.
        assert points[1][joint] - 300 <= max(targets) <= points[1][joint]
        assert targets[-1] == points[2][joint]
        settled = records.of(drive, "position")[-1]
        assert abs(settled - points[2][joint]) <= SETTLED, f"drive {drive} at {settled}"
    events = records.trajectory_events()
    assert [(e["id"], e["state"]) for e in events] == [(trajectory, "running"), (trajectory, "done")]


def test_a_trajectory_replaced_half_way_continues_without_a_step():
    on_the_rig(replaced_half_way)


def replaced_half_way(cycle, _simulator, records):
    base, times, points, first = play_three_points(cycle, records)
    records.wait(1000)
    back = [[float(b) for b in base]]
    second = cycle.play_trajectory(DRIVES, [S], back)
    status = records.until_ended(second)
    assert status["state"] == "done"
    replaced = cycle.trajectory_status(first)
    assert (replaced["state"], replaced["replaced_by"]) == ("replaced", second)
    assert replaced["point"] == 1, replaced
    records.wait(50)
    for joint, drive in enumerate(DRIVES):
        first_knots = knots_of(replaced, times, points, joint, base[joint])
        # The second starts where the first was at that instant.
        takeover = status["started_ns"]
        second_knots = [(takeover, linear_position(first_knots, takeover)), (takeover + S, back[0][joint])]
        knots = [k for k in first_knots if k[0] < takeover] + second_knots
        assert_continuous(records, drive, knots)
        assert records.of(drive, "target_position")[-1] == base[joint]


@pytest.mark.parametrize(
    ("change", "why"),
    [
        (lambda t, p, lim: (t, p, [(-1e9, p[0][0] + 10), *lim[1:]]), "point 1, joint 0: position"),
        (lambda t, p, lim: ([t[0], t[0], t[2]], p, lim), "point 1: time from the start 500000000 ns is not after"),
        (lambda t, p, lim: (t, [p[0], [p[1][0], math.nan, p[1][2]], p[2]], lim), "point 1, joint 1: position nan"),
        (lambda t, p, lim: (t, [p[0][:2], p[1], p[2]], lim), "point 0 gives 2 joint value(s); the trajectory has 3"),
        (lambda t, p, lim: (t[:2], p, lim), "3 point(s) but 2 time(s)"),
    ],
    ids=["limit", "non-increasing", "nan", "joint-count", "times"],
)
def test_a_refused_trajectory_leaves_every_axis_still(change, why):
    on_the_rig(lambda cycle, _simulator, records: refused(cycle, records, change, why))


def refused(cycle, records, change, why):
    records.wait(20)
    base = records.last_targets()
    times, points, limits = change(*three_points(base), [(-1e9, 1e9)] * 3)
    for joint, (drive, limit) in enumerate(zip(DRIVES, limits, strict=True)):
        cycle.set_joint_limits(drive, f"joint {joint}", limit)
    try:
        with pytest.raises(_native.ConfigError, match=r"^trajectory refused, nothing moved: ") as refused:
            cycle.play_trajectory(DRIVES, times, points)
    finally:
        for joint, drive in enumerate(DRIVES):
            cycle.set_joint_limits(drive, f"joint {joint}", (None, None))
    assert why.lower() in str(refused.value).lower()
    since = cycle.snapshot()["cycle"]
    records.wait(300)
    for joint, drive in enumerate(DRIVES):
        assert set(records.of(drive, "target_position", since)) == {base[joint]}
        assert all(abs(p - base[joint]) <= SETTLED for p in records.of(drive, "position", since))
    assert not records.trajectory_events()


def test_an_unknown_or_unready_drive_refuses_the_trajectory():
    with rig() as (cycle, _simulator):
        unready(cycle)


def unready(cycle):
    one = [[0.0]]
    with pytest.raises(_native.ConfigError, match=r"joint 0 \(drive 7\): no slave at position 7"):
        cycle.play_trajectory([7], [S], one)
    with pytest.raises(_native.ConfigError, match="drive 1 is named for joint 0 and joint 1"):
        cycle.play_trajectory([1, 1], [S], [[0.0, 0.0]])
    with pytest.raises(_native.ConfigError, match="drive 1 is named for wrist and elbow"):
        cycle.play_trajectory([1, 1], [S], [[0.0, 0.0]], names=["wrist", "elbow"])
    cycle.disable(2)
    cycle.wait_state(2, Ds402State.SWITCH_ON_DISABLED)
    with pytest.raises(_native.ConfigError, match=r"joint 0 \(drive 2\): it is in Switch on disabled"):
        cycle.play_trajectory([2], [S], one)
    # Named, as Bus.play_trajectory names them: what the user calls the joint.
    with pytest.raises(_native.ConfigError, match=r"nothing moved: joint_3 \(drive 2\): it is in Switch on disabled"):
        cycle.play_trajectory([2], [S], one, names=["joint_3"])
    with pytest.raises(_native.ConfigError, match="no trajectory 5: none was played"):
        cycle.trajectory_status(5)


def test_a_drive_faulted_mid_trajectory_aborts_it_and_the_others_hold():
    on_the_rig(faulted)


def faulted(cycle, simulator, records):
    base, _, _, trajectory = play_three_points(cycle, records, time.monotonic_ns() + S // 10)
    assert cycle.trajectory_status(trajectory)["state"] == "pending"
    records.wait(700)
    simulator.inject_fault(1, "F235")
    status = records.until_ended(trajectory)
    assert (status["state"], status["slave"]) == ("aborted", 1), status
    assert status["statusword"] & 0x0008, status
    assert status["elapsed_ns"] < status["duration_ns"]
    records.wait(200)
    (aborted,) = [e for e in records.trajectory_events() if e["state"] == "aborted"]
    for drive in (0, 2):
        held = records.of(drive, "target_position", aborted["cycle"])
        assert len(held) >= 200 and set(held) == {held[0]}, f"drive {drive} moved on"
        assert held[0] != base[drive]
    assert cycle.drive_status(1).state == Ds402State.FAULT
