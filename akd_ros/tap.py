"""A Linux TAP interface: Ethernet frames between the kernel's network stack and this process.

`akd-eoe` bridges one to the drives' IP stacks through EoE, so that the machine (or a network routed to it) reaches
the drives' addresses. Opening one needs CAP_NET_ADMIN; without it the error says so.
"""

from __future__ import annotations

import fcntl
import os
import select
import struct
import subprocess

# linux/if_tun.h
_TUNSETIFF = 0x400454CA
_IFF_TAP = 0x0002
_IFF_NO_PI = 0x1000
#: Longest frame read from the interface (1514 bytes and a VLAN tag, no FCS), as EoE carries them.
MAX_FRAME_LEN = 1518


class Tap:
    """An open TAP interface named `name` ("" lets the kernel choose), up, with `address` (CIDR) if given."""

    def __init__(self, name: str = "akd-eoe%d", address: str | None = None) -> None:
        if len(name.encode()) >= 16:
            raise ValueError(f"TAP interface name {name!r} is longer than 15 bytes")
        try:
            self._fd = os.open("/dev/net/tun", os.O_RDWR | os.O_CLOEXEC)
        except FileNotFoundError:
            raise OSError("/dev/net/tun is missing: this kernel or container has no TUN/TAP") from None
        except PermissionError:
            raise PermissionError(
                "/dev/net/tun is not open to this user: the distributions make it mode 0666 and let CAP_NET_ADMIN "
                "guard TAP interfaces; give this user access to it (a udev rule) or run as root"
            ) from None
        try:
            ifreq = fcntl.ioctl(self._fd, _TUNSETIFF, struct.pack("16sH", name.encode(), _IFF_TAP | _IFF_NO_PI))
        except PermissionError:
            os.close(self._fd)
            raise PermissionError(
                "opening a TAP interface needs CAP_NET_ADMIN (run as root, or setcap cap_net_admin)"
            ) from None
        self.name = ifreq[:16].rstrip(b"\0").decode()
        try:
            if address is not None:
                self._ip("addr", "add", address, "dev", self.name)
            self._ip("link", "set", self.name, "up")
        except BaseException:
            self.close()
            raise

    @staticmethod
    def _ip(*args: str) -> None:
        done = subprocess.run(["ip", *args], capture_output=True, text=True)
        if done.returncode != 0:
            raise OSError(f"ip {' '.join(args)}: {done.stderr.strip()}")

    def read(self, timeout: float) -> bytes | None:
        """The next frame the kernel sends through the interface, `None` after `timeout` s without one."""
        ready, _, _ = select.select([self._fd], [], [], timeout)
        return os.read(self._fd, MAX_FRAME_LEN) if ready else None

    def write(self, frame: bytes) -> None:
        """Hands one frame to the kernel as received on the interface."""
        os.write(self._fd, frame)

    def close(self) -> None:
        """Closes the interface (the kernel removes it)."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> Tap:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
