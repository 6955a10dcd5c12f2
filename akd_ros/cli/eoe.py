"""akd-eoe LINK --ip A.B.C.D/N ...: the drives' IP stacks reached through a TAP interface over Ethernet over EtherCAT.

Each --ip gives the drive at the next position (0, 1, ...) its address and subnet mask by EoE Set IP Parameter, with
a MAC of 02:01:05:30 and its station address (as TwinCAT gives one) and --gateway as its default gateway. The bus
then runs in Op with the cycle thread, which carries the Ethernet frames in EoE fragments beside the process data,
and a TAP interface (--tap, addressed --host) bridges the machine to them: `ping`, or WorkBench connecting by IP.
Frames for a broadcast or multicast address go to every drive, others to the drive with that MAC. Opening the TAP
interface needs CAP_NET_ADMIN. The tool runs until SIGINT/SIGTERM (or --duration) and prints the cycle's lost
process-data frames and working-counter errors, the frames carried and, counted apart, the mailbox frames lost
beside the process data (each sent again) when it stops.
"""

from __future__ import annotations

import argparse
import ipaddress
import sys
import threading

from akd_ros.cli.common import add_master_arguments, open_master, run


def _interface(text: str) -> ipaddress.IPv4Interface:
    try:
        return ipaddress.IPv4Interface(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected an IPv4 address with its prefix, e.g. 192.168.0.10/24: {text!r}"
        ) from None


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}")
    return value


def _cpu(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a CPU number (0, 1, ...), got {text!r}")
    return value


def _mac_text(mac: bytes) -> str:
    return ":".join(f"{b:02x}" for b in mac)


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-eoe."""
    parser = argparse.ArgumentParser(prog="akd-eoe", description=__doc__.splitlines()[0])
    add_master_arguments(parser)
    parser.add_argument(
        "--ip",
        type=_interface,
        action="append",
        required=True,
        metavar="A.B.C.D/N",
        help="address and prefix of the drive at the next position (give one per drive, from position 0)",
    )
    parser.add_argument(
        "--host", type=_interface, metavar="A.B.C.D/N", help="the TAP interface's own address (default: none)"
    )
    parser.add_argument("--gateway", metavar="A.B.C.D", help="the drives' default gateway (default: --host's address)")
    parser.add_argument("--tap", default="akd-eoe%d", metavar="NAME", help="TAP interface name (default akd-eoe%%d)")
    parser.add_argument(
        "--period", type=_seconds, default=0.001, metavar="SECONDS", help="cycle period (default 0.001 s)"
    )
    parser.add_argument("--duration", type=_seconds, metavar="SECONDS", help="stop after this long (default: never)")
    parser.add_argument(
        "--priority", type=int, metavar="N", help="the cycle thread under SCHED_FIFO N (where permitted)"
    )
    parser.add_argument("--cpu", type=_cpu, metavar="N", help="the cycle thread bound to CPU N (where permitted)")
    args = parser.parse_args(argv)
    gateway = args.gateway or (str(args.host.ip) if args.host else None)

    def body() -> int:
        from akd_ros import _native
        from akd_ros.eoe_bridge import EoeBridge
        from akd_ros.tap import Tap

        # The TAP interface first: on a network interface the master gives up CAP_NET_ADMIN with the rest once its
        # raw socket is open.
        tap = Tap(args.tap, str(args.host) if args.host else None)
        try:
            master = open_master(args)
        except BaseException:
            tap.close()
            raise
        try:
            count = len(master.scan())
            if len(args.ip) > count:
                raise ValueError(f"{len(args.ip)} --ip given but the bus has {count} drive(s)")
            master.request_state("preop")
            drives: dict[bytes, int] = {}
            for position, interface in enumerate(args.ip):
                mac = master.eoe_set_ip(
                    position, str(interface.ip), subnet_mask=str(interface.netmask), gateway=gateway
                )
                drives[bytes.fromhex(mac.replace(":", ""))] = position
            if _native.dc_by_default(args.link):
                master.configure_dc(round(args.period * 1e9), 0)
            else:
                master.configure_sm2_sync(round(args.period * 1e9))
            master.request_state("op")
            cycle = _native.Cycle(master, args.period, realtime=_native.RealTime(priority=args.priority, cpu=args.cpu))
            for warning in cycle.warnings:
                print(f"akd-eoe: warning: {warning}", file=sys.stderr, flush=True)
        except BaseException:
            master.close()
            tap.close()
            raise
        bridge = EoeBridge(cycle, drives, tap)
        try:
            for position, interface in enumerate(args.ip):
                mac = next(m for m, p in drives.items() if p == position)
                print(f"akd-eoe: drive {position} at {interface.ip} (MAC {_mac_text(mac)}) through {bridge.name}")
            sys.stdout.flush()
            # Until SIGINT/SIGTERM (or --duration): the bridge's threads carry the frames.
            threading.Event().wait(args.duration)
        finally:
            bridge.close()
            stats = cycle.stats()
            dropped = cycle.eoe_dropped()
            cycle.stop()
            master.close()
            print(
                f"akd-eoe: {stats['cycles']} cycles, {stats['lost_frames']} lost frames, {stats['wkc_errors']} WKC "
                f"errors; frames to the drives {bridge.to_drives}, from them {bridge.from_drives}, "
                f"dropped {dropped[0]} and {dropped[1]}; beside the process data {stats['acyclic_lost_frames']} "
                f"mailbox frames lost"
            )
            if bridge.refused:
                print(f"akd-eoe: {bridge.refused} frames from {bridge.name} too long for EoE, dropped", file=sys.stderr)
            if bridge.failure:
                print(f"akd-eoe: the bridge had stopped: {bridge.failure}", file=sys.stderr)
        return 0

    return run("akd-eoe", body)
