"""akd-foe LINK read|write NAME FILE: reads or writes one file on a drive by File access over EtherCAT (FoE).

`write` sends FILE's bytes to the drive as NAME; `read` stores the drive's file NAME in FILE ('-': standard output).
The drive is taken to PreOp first if it is in Init (FoE needs its mailbox). A progress bar shows the packets the
drive acknowledged. What the drive does with a file (a firmware image) is the drive's: the tool reports what the
drive answered and claims nothing more. A refusal (FoE error, e.g. 0x8001 "not found") is printed by name with the
drive's code and the tool exits with status 1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from akd_ros.cli.common import add_master_arguments, open_master, run


def _progress(description: str):
    """A rich progress bar on stderr (stdout may carry the file)."""
    from rich.console import Console
    from rich.progress import BarColumn, DownloadColumn, Progress, TransferSpeedColumn

    return Progress(description, BarColumn(), DownloadColumn(), TransferSpeedColumn(), console=Console(stderr=True))


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-foe."""
    parser = argparse.ArgumentParser(prog="akd-foe", description=__doc__.splitlines()[0])
    add_master_arguments(parser)
    parser.add_argument(
        "--position", type=int, default=0, metavar="N", help="the drive's position on the bus (default 0)"
    )
    parser.add_argument(
        "--password", type=lambda t: int(t, 0), default=0, metavar="P", help="FoE password, 32 bits (default 0)"
    )
    actions = parser.add_subparsers(dest="action", required=True, metavar="read|write")
    for action, what in (
        ("read", "read the drive's file NAME into FILE ('-': stdout)"),
        ("write", "write FILE as NAME"),
    ):
        sub = actions.add_parser(action, help=what)
        sub.add_argument("name", metavar="NAME")
        sub.add_argument("file", metavar="FILE")
    args = parser.parse_args(argv)
    if not 0 <= args.password <= 0xFFFF_FFFF:
        parser.error(f"--password must be 0..0xFFFFFFFF, got {args.password}")

    def body() -> int:
        data = Path(args.file).read_bytes() if args.action == "write" else None
        master = open_master(args)
        try:
            master.scan()
            if master.al_status(args.position)[0] == "Init":
                master.request_state("PreOp", args.position)
            progress = _progress(f"{args.action} {args.name}")
            with progress:
                task = progress.add_task(args.action, total=len(data) if data is not None else None)
                if data is not None:
                    master.foe_write(
                        args.position,
                        args.name,
                        data,
                        password=args.password,
                        progress=lambda sent, total: progress.update(task, completed=sent),
                    )
                    print(f"wrote {len(data)} bytes as {args.name!r}", file=sys.stderr)
                    return 0
                file = master.foe_read(
                    args.position,
                    args.name,
                    password=args.password,
                    progress=lambda received: progress.update(task, completed=received),
                )
                progress.update(task, total=len(file), completed=len(file))
            if args.file == "-":
                sys.stdout.buffer.write(file)
            else:
                Path(args.file).write_bytes(file)
            print(f"read {len(file)} bytes of {args.name!r}", file=sys.stderr)
        finally:
            master.close()
        return 0

    return run("akd-foe", body)
