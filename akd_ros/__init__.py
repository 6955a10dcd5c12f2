"""Kollmorgen AKD servo drives on EtherCAT, over the Rust EtherCAT master in `akd_ros._native`.

The public API, named here one by one (`__all__`), so that what the extension exports for the package's own use
(drive knowledge, codecs, the node's helpers) is not the user's API by accident:

- from the native extension: the `Master`, the real-time `Cycle` and its options (`RealTime`, which `Bus`, `Axis`
  and the node's `rt.*` parameters take alike), the CiA 402 states (`Ds402State`), the virtual AKD (`VirtualBus`,
  `serve_udp`, `serve_iface`, `Simulator`, which controls the virtual AKDs of a `Master("sim")` or a server while they
  serve, and `SetpointTrace`, the file a server traces their set-points to) and the exceptions, all under
  `EtherCatError`;
- in Python: `Bus`, one EtherCAT line with its master and cycle thread, and `Axis`, one drive on it commanded in SI
  units (`Units`, `Limits`), with its events; `Axis(link)` alone is a bus of one; `Device`, one of the line's other
  slaves (a terminal beside the drives: `DeviceConfig`), read and set by channel name (`DeviceIo`).

Everything else of the extension stays reachable as `akd_ros._native`, for the package and its tests.
"""

from akd_ros._native import (
    AlStateError,
    ConfigError,
    Cycle,
    Ds402State,
    EtherCatError,
    FoeError,
    FrameError,
    LinkError,
    MailboxError,
    Master,
    PdoError,
    RealTime,
    SdoAbortError,
    SetpointTrace,
    SiiError,
    Simulator,
    TimeoutError,  # noqa: A004  (the extension's own, an EtherCatError: a reply that did not come in time)
    VirtualBus,
    WorkingCounterError,
    serve_iface,
    serve_udp,
)
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
from akd_ros.device import Device, DeviceConfig, DeviceIo
from akd_ros.units import Limits, Units, unwrap_position

__all__ = [
    "MODES",
    "AlStateError",
    "Axis",
    "AxisIo",
    "AxisState",
    "Bus",
    "BusRequestError",
    "CommandError",
    "CommandTimeoutEvent",
    "ConfigError",
    "Cycle",
    "Device",
    "DeviceConfig",
    "DeviceIo",
    "DriveConfig",
    "Ds402State",
    "EtherCatError",
    "FaultEvent",
    "FoeError",
    "FrameError",
    "LatchEvent",
    "Limits",
    "LinkError",
    "MailboxError",
    "Master",
    "PdoError",
    "RealTime",
    "SdoAbortError",
    "SetpointTrace",
    "SiiError",
    "Simulator",
    "TimeoutError",
    "Units",
    "VirtualBus",
    "WorkingCounterError",
    "serve_iface",
    "serve_udp",
    "unwrap_position",
]
