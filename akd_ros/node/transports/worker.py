"""A callback group as a thread of its own: `Worker` runs its timers at absolute deadlines and the callbacks handed to
it, one at a time, as rclpy's mutually exclusive callback groups do; `WorkerGroups`, a transport's, made, started and
stopped together.

The Zenoh transport runs every group this way (Zenoh has no executor), and the rclpy one runs its timers this way:
a timer of rclpy's executor wakes it, and every wake-up rebuilds the executor's wait set over all of the node's
entities (about 90 with six joints), which cost most of the node's CPU at 250 Hz of /joint_states.
"""

from __future__ import annotations

import concurrent.futures
import heapq
import itertools
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

from akd_ros.node.threads import name_this_thread


def in_thread(name: str, callback: Callable[..., Any], *args) -> concurrent.futures.Future:
    """Runs `callback(*args)` on a new thread named `name`; its result or exception as a Future. For work that runs as
    long as a motion does (an action's goal), which would hold a group's one thread for that long."""
    future: concurrent.futures.Future = concurrent.futures.Future()

    def run() -> None:
        name_this_thread(name)
        try:
            future.set_result(callback(*args))
        except BaseException as e:  # noqa: BLE001  (handed to whoever awaits the future)
            future.set_exception(e)

    threading.Thread(target=run, name=name, daemon=True).start()
    return future


class Worker:
    """A callback group: one thread (named `name`) that runs its timers and the callbacks submitted to it, one at a
    time; a callback that raises is logged through `logger` and the group goes on."""

    def __init__(self, name: str, logger) -> None:
        self._queue: queue.Queue = queue.Queue()
        self._timers: list[tuple[float, int, float, Callable[[], None]]] = []
        self._order = itertools.count()
        self._stopped = False
        self._logger = logger
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    @property
    def name(self) -> str:
        """Its thread's name."""
        return self._thread.name

    def start(self) -> None:
        self._thread.start()

    def add_timer(self, period: float, callback: Callable[[], None]) -> None:
        heapq.heappush(self._timers, (time.monotonic() + period, next(self._order), period, callback))

    def submit(self, callback: Callable[..., Any], *args) -> concurrent.futures.Future:
        future: concurrent.futures.Future = concurrent.futures.Future()
        self._queue.put((future, callback, args))
        return future

    def stop(self) -> None:
        self._stopped = True
        self._queue.put(None)
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        name_this_thread(self._thread.name)
        while not self._stopped:
            timeout = max(0.0, self._timers[0][0] - time.monotonic()) if self._timers else None
            try:
                item = self._queue.get(timeout=timeout)
            except queue.Empty:
                item = False
            if item is None:
                return
            if item:
                future, callback, args = item
                try:
                    future.set_result(callback(*args))
                except Exception as e:  # noqa: BLE001  (a callback's failure is logged, the group goes on)
                    self._logger.error(f"callback failed: {type(e).__name__}: {e}")
                    future.set_exception(e)
            now = time.monotonic()
            while self._timers and self._timers[0][0] <= now:
                due, order, period, callback = heapq.heappop(self._timers)
                # Absolute deadlines; a late run does not push the next one back, a very late one skips.
                heapq.heappush(self._timers, (max(due + period, now), order, period, callback))
                try:
                    callback()
                except Exception as e:  # noqa: BLE001
                    self._logger.error(f"timer callback failed: {type(e).__name__}: {e}")


class WorkerGroups:
    """What a transport whose callback groups run on `Worker` threads has of them: `group(name)` makes one, `start()`
    runs their threads once the parts are made, `close()` stops them."""

    def __init__(self, logger) -> None:
        self.logger = logger
        self._workers: list[Worker] = []

    def start(self) -> None:
        for worker in self._workers:
            worker.start()

    def close(self) -> None:
        for worker in self._workers:
            worker.stop()

    def group(self, name: str) -> Worker:
        worker = Worker(f"akd-{name}", self.logger)
        self._workers.append(worker)
        return worker
