"""What the command-line tools share: the LINK argument, one-line errors, exit statuses."""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable

LINK_HELP = (
    "the bus: 'sim' (one in-process virtual AKD), 'sim:N' (N of them), "
    "'udp://HOST:PORT' (akd-sim --udp), or a network interface name (needs CAP_NET_RAW)"
)

#: Exit status of a tool that failed (bus, drive or argument error).
EXIT_FAILURE = 1
#: Exit status after SIGINT, as a shell reports it.
EXIT_INTERRUPTED = 130


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


def stop_on_signals() -> None:
    """Makes SIGINT and SIGTERM end the tool through Python, so it cleans up. SIGINT's too: a process started with
    it ignored (a shell's background job, a CI runner) inherits that, and Python then leaves it ignored, so the tool
    would not stop on it at all."""

    def handler(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, handler)


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
