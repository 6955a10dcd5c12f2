"""The drives' IP stacks reached from the machine: a TAP interface bridged to a running Cycle's EoE.

Two threads carry the frames: one reads the TAP interface and hands each frame to `Cycle.eoe_send` of the drive with
its destination MAC (broadcast and multicast to every drive), the other takes what `Cycle.eoe_receive` gives and
writes it to the TAP interface. The cycle thread fragments and reassembles them beside the process data. `akd-eoe`
and the node (parameter eoe.tap) both open one.
"""

from __future__ import annotations

import threading

from akd_ros import _native
from akd_ros.tap import Tap

_POLL = 0.1
"""How long each thread waits for a frame before it looks whether it is to stop, s."""


class EoeBridge:
    """The open TAP interface `tap` bridged to the drives of `drives` (MAC -> position) through `cycle`; `close()`
    stops it and removes the interface.

    The interface is opened (`Tap`, which needs CAP_NET_ADMIN) before the master opens its link: on a network
    interface the master gives up every capability it does not need once its raw socket is open."""

    def __init__(self, cycle, drives: dict[bytes, int], tap: Tap) -> None:
        self._cycle, self._drives = cycle, dict(drives)
        self.to_drives = 0
        """Frames handed to the cycle for the drives."""
        self.from_drives = 0
        """Frames from the drives written to the interface."""
        self.refused = 0
        """Frames the cycle refused to carry (longer than EoE takes), dropped."""
        self.failure: str | None = None
        """Why a thread stopped before `close()` (the interface or the cycle gone), if one did."""
        self._stop = threading.Event()
        self._tap = tap
        self.name = tap.name
        """The interface's name, as the kernel gave it."""
        self._threads = [
            threading.Thread(target=self._to_drives, name="akd-eoe-tap", daemon=True),
            threading.Thread(target=self._from_drives, name="akd-eoe-cycle", daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    def _to_drives(self) -> None:
        every = tuple(self._drives.values())
        while not self._stop.is_set():
            try:
                frame = self._tap.read(_POLL)
            except OSError as e:
                self._failed(f"reading {self.name}: {e}")
                return
            if frame is None or len(frame) < 14:
                continue
            # Bit 0 of the first byte: a group (broadcast or multicast) address.
            position = self._drives.get(frame[:6])
            for target in every if frame[0] & 1 else () if position is None else (position,):
                try:
                    self._cycle.eoe_send(target, frame)
                except _native.MailboxError:
                    self.refused += 1
                    continue
                self.to_drives += 1

    def _from_drives(self) -> None:
        while not self._stop.is_set():
            received = self._cycle.eoe_receive(_POLL)
            if received is not None:
                try:
                    self._tap.write(received[1])
                except OSError as e:
                    self._failed(f"writing {self.name}: {e}")
                    return
                self.from_drives += 1

    def _failed(self, why: str) -> None:
        # A thread's exception would print a traceback; the owner reports this at close instead.
        self.failure = why

    def close(self) -> None:
        """Stops both threads (within `_POLL`) and removes the interface; before the cycle stops."""
        self._stop.set()
        for thread in self._threads:
            thread.join()
        self._tap.close()

    def __enter__(self) -> EoeBridge:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
