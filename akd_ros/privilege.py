"""The one warning about privilege: no tool and not the node need root, CAP_NET_RAW alone opens a raw interface (the
node and the tools that open a link give it; akd-plot, which reads bags, needs no capability).

What happens to the capabilities once the socket is open is the native link's
(native/src/ethercat/link/privilege.rs)."""

from __future__ import annotations

import os
import sys

ROOT_WARNING = (
    "running as root is not needed; CAP_NET_RAW is enough, with CAP_NET_ADMIN for an EoE TAP interface "
    "(docs/howto/without_root.md)"
)


def warn_if_root(prog: str) -> None:
    """One line on stderr, at start, when the effective user is root."""
    if os.geteuid() == 0:
        print(f"{prog}: warning: {ROOT_WARNING}", file=sys.stderr, flush=True)
