"""akd-sdo LINK read INDEX:SUB | write INDEX:SUB VALUE: reads or writes one object by CoE SDO.

INDEX, SUB and VALUE take hex (0x...) or decimal. The value's type and size come from the drive's
SDO information (entry description), so `write 0x6060:0 8` sends one byte. On an SDO abort the
tool prints the abort code with its name and exits with status 1.
"""

from __future__ import annotations

import argparse
import struct
import sys

from akd_ros import _native
from akd_ros.cli.common import add_master_arguments, open_master, run

# IEEE 754 numbers by their size in bytes (REAL32, REAL64).
_REAL_FORMATS = {4: "<f", 8: "<d"}
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
        value = int.from_bytes(data, "little", signed=kind == "signed_integer")
        return f"{value} (0x{data[::-1].hex().upper()})"
    if kind == "real" and len(data) in _REAL_FORMATS:
        return repr(struct.unpack(_REAL_FORMATS[len(data)], data)[0])
    if kind == "visible_string":
        return repr(data.rstrip(b"\0").decode("latin-1"))
    return data.hex(" ") if data else "(empty)"


def encode_value(text: str, data_type: int | None, size: int) -> bytes:
    """Encodes VALUE for an object of `data_type` and `size` bytes; ValueError when it cannot."""
    kind = _kind(data_type)
    if kind == "visible_string":
        return text.encode("latin-1")
    if kind == "real" and size in _REAL_FORMATS:
        return struct.pack(_REAL_FORMATS[size], float(text))
    try:
        value = int(text, 0)
    except ValueError:
        raise ValueError(f"expected a number in hex (0x...) or decimal, got {text!r}") from None
    signed = kind == "signed_integer"
    low, high = (-(1 << (8 * size - 1)), (1 << (8 * size - 1)) - 1) if signed else (0, (1 << (8 * size)) - 1)
    if not low <= value <= high:
        type_name = _native.data_type_name(data_type) if kind in _INTEGER_KINDS else f"{size}-byte value"
        raise ValueError(f"{text} is out of range for {type_name} ({low}..{high})")
    return value.to_bytes(size, "little", signed=signed)


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-sdo."""
    parser = argparse.ArgumentParser(prog="akd-sdo", description=__doc__.splitlines()[0])
    add_master_arguments(parser)
    parser.add_argument(
        "--position", type=int, default=0, metavar="N", help="the slave's position on the bus (default 0)"
    )
    parser.add_argument(
        "--size", type=int, metavar="BYTES", help="size of a written integer, for drives without SDO information"
    )
    actions = parser.add_subparsers(dest="action", required=True, metavar="read|write")
    read = actions.add_parser("read", help="read INDEX:SUB")
    read.add_argument("address", metavar="INDEX:SUB")
    write = actions.add_parser("write", help="write VALUE to INDEX:SUB")
    write.add_argument("address", metavar="INDEX:SUB")
    write.add_argument("value", metavar="VALUE")
    args = parser.parse_args(argv)

    def body() -> int:
        from akd_ros import EtherCatError

        index, subindex = parse_address(args.address)
        master = open_master(args)
        try:
            master.scan()
            if master.al_status(args.position)[0] == "Init":
                master.request_state("PreOp", args.position)
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


if __name__ == "__main__":
    sys.exit(main())
