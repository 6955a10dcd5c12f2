"""One AKD as an Axis, moved in profile position: the drive's own profile generator takes each target to the end.

    .venv/bin/python examples/axis_profile_position.py            # the built-in virtual AKD
    .venv/bin/python examples/axis_profile_position.py enp3s0     # a real drive (needs CAP_NET_RAW)

"sim?missed=lost" makes the virtual drive count only frames the line lost as missed, so a host that runs a cycle
late (a laptop, a shared VM) does not fault it with F125 as it would a real drive.
"""

import sys
import time

from akd_ros import Axis, Limits, Units

STATUSWORD_TARGET_REACHED = 0x0400


def wait_until_reached(axis: Axis, target: float, timeout: float = 10.0) -> float:
    """Waits for statusword bit 10 (target reached) near `target`; gives the position (rad)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = axis.state()
        if state.statusword & STATUSWORD_TARGET_REACHED and abs(state.position - target) < 1e-3:
            return state.position
        time.sleep(0.01)
    raise TimeoutError(f"the axis did not reach {target:.3f} rad within {timeout} s")


link = sys.argv[1] if len(sys.argv) > 1 else "sim?missed=lost"
with Axis(link, mode="profile_position", units=Units(gear_ratio=10.0), limits=Limits(max_velocity=5.0)) as axis:
    axis.enable()  # Operation enabled; the axis holds where it is until a target arrives
    start = axis.state().position
    for offset in (0.5, -0.25, 0.0):
        axis.command_position(start + offset)  # rad of the load; returns once the drive acknowledged the set-point
        print(f"at {wait_until_reached(axis, start + offset):+.4f} rad (target {start + offset:+.4f})")
    axis.disable()
