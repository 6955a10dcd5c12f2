"""Kollmorgen AKD servo drives on EtherCAT, over the Rust EtherCAT master in `akd_ros._native`.

Everything public here comes from the native extension: the `Master`, the virtual AKD
(`VirtualBus`, `serve_udp`, `serve_iface`, and `Simulator`, which controls the virtual AKDs of a
`Master("sim")` or a server while they serve) and the exceptions, all under `EtherCatError`.
"""

from akd_ros import _native
from akd_ros._native import *  # noqa: F401,F403  (the native module is the API)

__all__ = [name for name in dir(_native) if not name.startswith("_")]
