"""akd-sdo LINK read INDEX:SUB | write INDEX:SUB VALUE: reads or writes one object by CoE SDO.

INDEX, SUB and VALUE take hex (0x...) or decimal. The value's type and size come from the drive's
SDO information (entry description), so `write 0x6060:0 8` sends one byte. On an SDO abort the
tool prints the abort code with its name and exits with status 1.
"""

from __future__ import annotations

import argparse
import struct
import sys

from akd_ros.cli.common import add_master_arguments, open_master, run

# CoE data type codes (ETG.1000.6 table 64) the tool can show as numbers or text.
_SIGNED = {
    0x0002: "INTEGER8",
    0x0003: "INTEGER16",
    0x0004: "INTEGER32",
    0x0010: "INTEGER24",
    0x0012: "INTEGER40",
    0x0013: "INTEGER48",
    0x0014: "INTEGER56",
    0x0015: "INTEGER64",
}
_UNSIGNED = {
    0x0001: "BOOLEAN",
    0x0005: "UNSIGNED8",
    0x0006: "UNSIGNED16",
    0x0007: "UNSIGNED32",
    0x0016: "UNSIGNED24",
    0x0018: "UNSIGNED40",
    0x0019: "UNSIGNED48",
    0x001A: "UNSIGNED56",
    0x001B: "UNSIGNED64",
}
_REAL = {0x0008: "<f", 0x0011: "<d"}
_VISIBLE_STRING = 0x0009


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
    if data_type in _SIGNED or data_type in _UNSIGNED:
        value = int.from_bytes(data, "little", signed=data_type in _SIGNED)
        return f"{value} (0x{data[::-1].hex().upper()})"
    if data_type in _REAL and len(data) == struct.calcsize(_REAL[data_type]):
        return repr(struct.unpack(_REAL[data_type], data)[0])
    if data_type == _VISIBLE_STRING:
        return repr(data.rstrip(b"\0").decode("latin-1"))
    return data.hex(" ") if data else "(empty)"


def encode_value(text: str, data_type: int | None, size: int) -> bytes:
    """Encodes VALUE for an object of `data_type` and `size` bytes; ValueError when it cannot."""
    if data_type == _VISIBLE_STRING:
        return text.encode("latin-1")
    if data_type in _REAL:
        return struct.pack(_REAL[data_type], float(text))
    try:
        value = int(text, 0)
    except ValueError:
        raise ValueError(f"expected a number in hex (0x...) or decimal, got {text!r}") from None
    signed = data_type in _SIGNED
    low, high = (-(1 << (8 * size - 1)), (1 << (8 * size - 1)) - 1) if signed else (0, (1 << (8 * size)) - 1)
    if not low <= value <= high:
        type_name = _SIGNED.get(data_type) or _UNSIGNED.get(data_type) or f"{size}-byte value"
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
