"""akd-sim: serves virtual AKDs on a UDP port or a network interface until SIGINT/SIGTERM.

With --udp the EtherCAT payload travels as the UDP payload (the master's 'udp://HOST:PORT'
link); with --iface the virtual AKDs answer raw EtherCAT frames on that interface as a real
line of drives would (for a veth end, or a spare port wired to a master).
"""

from __future__ import annotations

import argparse
import signal
import sys

from akd_ros.cli.common import run


def parse_host_port(text: str) -> tuple[str, int]:
    """Splits 'HOST:PORT' ('[::1]:PORT' for IPv6); raises ValueError naming the problem."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"--udp expects HOST:PORT with a port in 1..65535, got {text!r}")
    return host.strip("[]"), int(port)


def count_argument(text: str) -> int:
    """The --count value: at least one virtual AKD."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expects a whole number of drives >= 1, got {text!r}")
    return int(text)


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-sim."""
    parser = argparse.ArgumentParser(prog="akd-sim", description=__doc__.splitlines()[0])
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--udp", metavar="HOST:PORT", help="serve EtherCAT over UDP here")
    where.add_argument("--iface", metavar="NAME", help="serve raw EtherCAT on this interface")
    parser.add_argument("--count", type=count_argument, default=1, metavar="N",
                        help="number of virtual AKDs in the line (default 1)")
    args = parser.parse_args(argv)

    def body() -> int:
        from akd_ros import serve_iface, serve_udp

        drives = f"{args.count} virtual AKD{'s' if args.count > 1 else ''}"
        try:
            if args.udp:
                host, port = parse_host_port(args.udp)
                print(f"akd-sim: starting {drives} on udp {host}:{port}", flush=True)
                serve_udp(host, port, args.count)
            else:
                print(f"akd-sim: starting {drives} on interface {args.iface}", flush=True)
                serve_iface(args.iface, args.count)
        except KeyboardInterrupt:
            # SIGINT and SIGTERM are how a simulator is meant to stop; a second signal while
            # it stops must not turn the clean stop into an interrupted one.
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        print("akd-sim: stopped", flush=True)
        return 0

    return run("akd-sim", body)


if __name__ == "__main__":
    sys.exit(main())
