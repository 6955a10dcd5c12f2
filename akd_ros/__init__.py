"""Kollmorgen AKD servo drives on EtherCAT, over the Rust EtherCAT master in `akd_ros._native`.

From the native extension: the `Master`, the real-time `Cycle`, the virtual AKD (`VirtualBus`,
`serve_udp`, `serve_iface`, `Simulator`, which controls the virtual AKDs of a
`Master("sim")` or a server while they serve, and `SetpointTrace`, the file a server traces their set-points to) and
the exceptions, all under `EtherCatError`.
In Python: `Bus`, one EtherCAT line with its master and cycle thread, and `Axis`, one drive on it commanded in SI
units (`Units`, `Limits`), with its events; `Axis(link)` alone is a bus of one.
"""

from akd_ros import _native
from akd_ros._native import *  # noqa: F403  (the native module is the API)
from akd_ros.axis import (
    MODES,
    Axis,
    AxisIo,
    AxisState,
    CommandError,
    CommandTimeoutEvent,
    DriveConfig,
    FaultEvent,
    LatchEvent,
)
from akd_ros.bus import Bus, BusRequestError
from akd_ros.units import Limits, Units, unwrap_position

__all__ = [name for name in dir(_native) if not name.startswith("_")] + [
    "MODES",
    "Axis",
    "AxisIo",
    "AxisState",
    "Bus",
    "BusRequestError",
    "CommandError",
    "CommandTimeoutEvent",
    "DriveConfig",
    "FaultEvent",
    "LatchEvent",
    "Limits",
    "Units",
    "unwrap_position",
]
