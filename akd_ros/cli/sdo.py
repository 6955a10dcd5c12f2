"""akd-sdo LINK read INDEX:SUB | write INDEX:SUB VALUE | dump -o FILE | restore FILE: one object by CoE SDO, or a
drive's whole configuration.

INDEX, SUB and VALUE take hex (0x...) or decimal. The value's type and size come from the drive's
SDO information (entry description), so `write 0x6060:0 8` sends one byte. On an SDO abort the
tool prints the abort code with its name and exits with status 1.

`dump` reads every readable entry the drive lists in its SDO information into a YAML file; `restore` writes the
writable ones that differ back, in an order the drive accepts (see akd_ros/cli/backup.py), reports each refusal with
its abort code and name, goes on with the rest, and ends with a summary; status 1 when any write was refused.
`restore --dry-run` shows what would change and writes nothing.
"""

from __future__ import annotations

import struct
import sys

from akd_ros import _native
from akd_ros.cli import backup
from akd_ros.cli.backup import REAL_FORMATS
from akd_ros.cli.common import EXIT_FAILURE, add_master_arguments, open_master, run, tool_parser

EXAMPLES = """examples:
  akd-sdo sim read 0x6060:0
  akd-sdo udp://127.0.0.1:34980 write 0x6065:0 1048576
  akd-sdo enp3s0 --position 1 dump -o drive.yaml
  akd-sdo enp3s0 --position 1 restore drive.yaml --dry-run
"""

_INTEGER_KINDS = ("signed_integer", "unsigned_integer")


def _kind(data_type: int | None) -> str:
    """How values of a CoE data type read, by the extension's table ("other" without SDO information)."""
    return "other" if data_type is None else _native.data_type_kind(data_type)


def parse_address(text: str) -> tuple[int, int]:
    """'INDEX:SUB' in hex or decimal; raises ValueError naming the allowed ranges."""
    index_text, _, sub_text = text.partition(":")
    try:
        index, subindex = int(index_text, 0), int(sub_text, 0)
    except ValueError:
        raise ValueError(f"expected INDEX:SUB such as 0x6060:0, got {text!r}") from None
    if not 0 <= index <= 0xFFFF or not 0 <= subindex <= 0xFF:
        raise ValueError(f"index must be 0..0xFFFF and subindex 0..0xFF, got {text!r}")
    return index, subindex


def format_value(data: bytes, data_type: int | None) -> str:
    """Shows an SDO value as its data type reads (number, text), or as hex bytes."""
    kind = _kind(data_type)
    if kind in _INTEGER_KINDS:
        return f"{backup.decode(data, data_type)} (0x{data[::-1].hex().upper()})"
    if kind == "visible_string" or (kind == "real" and len(data) in REAL_FORMATS):
        return repr(backup.decode(data, data_type))
    return data.hex(" ") if data else "(empty)"


def encode_value(text: str, data_type: int | None, size: int) -> bytes:
    """Encodes VALUE for an object of `data_type` and `size` bytes; ValueError when it cannot."""
    kind = _kind(data_type)
    if kind == "visible_string":
        return text.encode("latin-1")
    if kind == "real" and size in REAL_FORMATS:
        return struct.pack(REAL_FORMATS[size], float(text))
    try:
        value = int(text, 0)
    except ValueError:
        raise ValueError(f"expected a number in hex (0x...) or decimal, got {text!r}") from None
    type_name = _native.data_type_name(data_type) if kind in _INTEGER_KINDS else f"{size}-byte value"
    return backup.integer_bytes(value, kind == "signed_integer", size, type_name)


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-sdo."""
    parser = tool_parser(
        "akd-sdo",
        "Reads or writes one object of a drive by CoE SDO, or dumps or restores its whole configuration.",
        EXAMPLES,
    )
    add_master_arguments(parser)
    parser.add_argument(
        "--position", type=int, default=0, metavar="N", help="the slave's position on the bus (default 0)"
    )
    parser.add_argument(
        "--size", type=int, metavar="BYTES", help="size of a written integer, for drives without SDO information"
    )
    actions = parser.add_subparsers(dest="action", required=True, metavar="read|write|dump|restore")
    read = actions.add_parser("read", help="read INDEX:SUB")
    read.add_argument("address", metavar="INDEX:SUB")
    write = actions.add_parser("write", help="write VALUE to INDEX:SUB")
    write.add_argument("address", metavar="INDEX:SUB")
    write.add_argument("value", metavar="VALUE")
    dump = actions.add_parser("dump", help="read every readable object the drive lists into a YAML file")
    dump.add_argument("-o", "--output", required=True, metavar="FILE", help="the YAML file to write")
    restore = actions.add_parser("restore", help="write a dump's writable objects back")
    restore.add_argument("file", metavar="FILE", help="a YAML file akd-sdo dump wrote")
    restore.add_argument("--dry-run", action="store_true", help="show what would change, write nothing")
    args = parser.parse_args(argv)

    def body() -> int:
        from akd_ros import EtherCatError

        records = backup.read_file(args.file) if args.action == "restore" else None
        index, subindex = parse_address(args.address) if args.action in ("read", "write") else (0, 0)
        master = open_master(args)
        try:
            slaves = master.scan()
            if not 0 <= args.position < len(slaves):
                raise ValueError(f"--position {args.position} is not on the bus (positions 0..{len(slaves) - 1})")
            if master.al_status(args.position)[0] == "Init":
                master.request_state("PreOp", args.position)
            if args.action == "dump":
                return _dump(master, args.position, slaves[args.position], args.output)
            if args.action == "restore":
                return _restore(master, args.position, records, args.dry_run)
            if args.action == "read":
                data = master.sdo_read(args.position, index, subindex)
                try:
                    entry = master.sdo_entry_description(args.position, index, subindex)
                except EtherCatError:
                    entry = None  # not every slave describes every entry: show the raw bytes
                shown = format_value(data, entry["data_type"] if entry else None)
                print(f"0x{index:04X}:{subindex:02X} = {shown}")
            else:
                if args.size is None:
                    entry = master.sdo_entry_description(args.position, index, subindex)
                    data_type, size = entry["data_type"], (entry["bit_length"] + 7) // 8
                else:
                    data_type, size = None, args.size
                data = encode_value(args.value, data_type, size)
                master.sdo_write(args.position, index, subindex, data)
                print(f"0x{index:04X}:{subindex:02X} <- {format_value(data, data_type)}")
        finally:
            master.close()
        return 0

    return run("akd-sdo", body)


def _progress(iterable, total: int):
    """`iterable` under a progress bar on stderr (rich's), as the objects are read."""
    from rich.console import Console
    from rich.progress import Progress

    with Progress(console=Console(stderr=True), transient=False) as progress:
        yield from progress.track(iterable, total=total, description="reading objects")


def _dump(master, position: int, slave: dict, path: str) -> int:
    records, notes = backup.dump(master, position, _progress)
    drive = {"position": position, **{k: slave.get(k) for k in ("name", "vendor_id", "product_code", "serial_number")}}
    backup.write_file(path, drive, records)
    for note in notes:
        print(f"note: {note}")
    print(f"dumped {len(records)} entries to {path} ({len(notes)} skipped)")
    return 0


def _restore(master, position: int, records: list[dict], dry_run: bool) -> int:
    plan = backup.plan(master, position, records)
    for note in plan.skipped:
        print(f"note: {note}")
    if dry_run:
        for write in plan.writes:
            if write.step:
                print(f"would write {write.where} {write.name} <- {write.value!r} (a step of the order)")
            else:
                print(f"would change {write.where} {write.name}: {write.before!r} -> {write.value!r}")
        for refusal in plan.refused:
            print(f"would refuse {refusal}")
        changes = sum(not w.step for w in plan.writes)
        print(
            f"dry run: {changes} would change, {plan.unchanged} unchanged, {len(plan.skipped)} skipped, "
            f"{len(plan.refused)} not writable as given; nothing written"
        )
        return 0
    failed = backup.execute(master, position, plan.writes)
    refused = plan.refused + [text for _, text in failed]
    for refusal in refused:
        print(f"refused: {refusal}")
    written = sum(not w.step for w in plan.writes) - sum(not w.step for w, _ in failed)
    print(
        f"restored: {written} written, {plan.unchanged} unchanged, {len(plan.skipped)} skipped, {len(refused)} refused"
    )
    return EXIT_FAILURE if refused else 0


if __name__ == "__main__":
    sys.exit(main())
