"""What the command-line tools share: the LINK argument, one-line errors, exit statuses."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
from collections.abc import Callable, Iterator

LINK_HELP = (
    "the bus: 'sim' (one in-process virtual AKD), 'sim:N' (N of them), "
    "'udp://HOST:PORT' (akd-sim --udp), or a network interface name (needs CAP_NET_RAW)"
)

#: Exit status of a tool that failed (bus, drive or argument error).
EXIT_FAILURE = 1
#: Exit status after SIGINT, as a shell reports it.
EXIT_INTERRUPTED = 130


def tool_parser(prog: str, description: str, examples: str) -> argparse.ArgumentParser:
    """A tool's argument parser: its name, what it does in a line, and its examples after the options, as written."""
    return argparse.ArgumentParser(
        prog=prog, description=description, epilog=examples, formatter_class=argparse.RawDescriptionHelpFormatter
    )


def add_master_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds LINK and the options every tool that opens a master takes."""
    parser.add_argument("link", metavar="LINK", help=LINK_HELP)
    parser.add_argument(
        "--timeout", type=float, default=0.1, metavar="SECONDS", help="reply time-out of one frame (default 0.1 s)"
    )
    parser.add_argument("--pcap", metavar="FILE", help="write every frame sent and received to this pcapng file")


def open_master(args: argparse.Namespace):
    """Opens the master on the LINK given on the command line."""
    from akd_ros import Master

    return Master(args.link, pcap=args.pcap, timeout=args.timeout)


_held: list[int] | None = None
"""The signals `stop_on_signals`'s handler has held back, while `signals_held` holds them (None otherwise)."""


def stop_on_signals() -> None:
    """Makes SIGINT and SIGTERM end the tool through Python, so it cleans up. SIGINT's too: a process started with
    it ignored (a shell's background job, a CI runner) inherits that, and Python then leaves it ignored, so the tool
    would not stop on it at all."""

    def handler(signum, frame):
        if _held is None:
            raise KeyboardInterrupt(f"signal {signum}")
        _held.append(signum)

    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, handler)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Holds SIGINT and SIGTERM back while the block runs, then stops as they would have (KeyboardInterrupt), for code
    that an exception at any line would leave broken: threading's start of a thread, interrupted, left its locks
    taken ("release unlocked lock", or no thread could start or end after it). Their handler runs in the main thread
    whichever thread the signal reaches, so masking them (pthread_sigmask) in this thread alone would not hold them."""
    global _held
    _held = []
    try:
        yield
    finally:
        held, _held = _held, None
        if held:
            raise KeyboardInterrupt(f"signal {held[0]}")


def run(prog: str, body: Callable[[], int], *, opens_a_link: bool = True) -> int:
    """Runs a tool's body: a warning first when a tool that opens a link runs as root, EtherCAT
    errors and bad values become one line on stderr and a non-zero status, SIGINT/SIGTERM a
    quiet stop."""
    from akd_ros import EtherCatError
    from akd_ros.privilege import warn_if_root

    if opens_a_link:
        warn_if_root(prog)
    stop_on_signals()
    try:
        return body()
    except (EtherCatError, ValueError, OSError) as error:
        print(f"{prog}: error: {error}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
