"""A drive's configuration as a YAML file: `dump` reads every readable entry the drive lists in its SDO information,
`restore` writes the writable ones back in an order the drive accepts.

The file holds one record per entry: index, subindex, the object's and the entry's name, the CoE data type, the
access bits (as `_native.access_names` names them) and the value (a number, a text for a VISIBLE_STRING, hex bytes for
any other type). Restore asks the drive it writes to for each entry's description: an object that drive does not
list, an entry it does not describe and an entry it does not let be written in PreOp are skipped with a note; an
entry whose value is what the drive already holds is left alone. It writes in this order:

1. with any PDO mapping (0x1600-0x17FF, 0x1A00-0x1BFF) or assignment (0x1C12, 0x1C13) to change: both assignments'
   counts (subindex 0) to 0, so that no assigned PDO changes under the drive;
2. each mapping object to change: its count to 0 (the AKD takes entries only then), its entries, its count;
3. the assignments' entries, then their counts, back to the file's (or the drive's own) values;
4. every other entry, by index and subindex; 0x60C2 (interpolation time period) whole, units then index, when
   either changes, since the drive checks the pair when the index is written.

Each refusal is reported with its SDO abort code and name, and the restore goes on with the rest.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml

from akd_ros import _native

REAL_FORMATS = {4: "<f", 8: "<d"}
"""IEEE 754 numbers by their size in bytes (REAL32, REAL64), as struct formats."""
FILE_FORMAT = 1
"""The version of the dump file's layout, written as `format`."""


class _Hex(int):
    """An index written as hex in the file (YAML reads 0x... back as an integer)."""


yaml.SafeDumper.add_representer(_Hex, lambda dumper, value: dumper.represent_int(f"0x{value:04X}"))


def decode(data: bytes, data_type: int) -> int | float | str:
    """A value as the file holds it: an integer, a real, a text, or hex bytes for other types."""
    kind = _native.data_type_kind(data_type)
    if kind in ("signed_integer", "unsigned_integer"):
        return int.from_bytes(data, "little", signed=kind == "signed_integer")
    if kind == "real" and len(data) in REAL_FORMATS:
        return struct.unpack(REAL_FORMATS[len(data)], data)[0]
    if kind == "visible_string":
        return data.rstrip(b"\0").decode("latin-1")
    return data.hex()


def integer_bytes(value: int, signed: bool, size: int, type_name: str) -> bytes:
    """`value` as a little-endian integer of `size` bytes; ValueError naming `type_name` and its range if it does not
    fit."""
    bits = 8 * size
    low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    if not low <= value <= high:
        raise ValueError(f"{value} is out of range for {type_name} ({low}..{high})")
    return value.to_bytes(size, "little", signed=signed)


def encode(value, data_type: int, size: int) -> bytes:
    """The bytes of `value` (as `decode` gives it) for an entry of `data_type` and `size` bytes; ValueError naming
    what is wrong when it does not fit."""
    kind = _native.data_type_kind(data_type)
    name = _native.data_type_name(data_type)
    if kind in ("signed_integer", "unsigned_integer"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"expected an integer for {name}, got {value!r}")
        return integer_bytes(value, kind == "signed_integer", size, name)
    if kind == "real" and size in REAL_FORMATS:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"expected a number for {name}, got {value!r}")
        return struct.pack(REAL_FORMATS[size], value)
    if not isinstance(value, str):
        raise ValueError(f"expected a {'text' if kind == 'visible_string' else 'hex string'} for {name}, got {value!r}")
    if kind == "visible_string":
        return value.encode("latin-1")
    try:
        return bytes.fromhex(value)
    except ValueError:
        raise ValueError(f"expected hex bytes for {name}, got {value!r}") from None


def _readable(access: int) -> bool:
    return "read_preop" in _native.access_names(access)


def _writable(access: int) -> bool:
    return "write_preop" in _native.access_names(access)


def _abort_text(error: Exception) -> str:
    code = getattr(error, "code", None)
    return f"abort 0x{code:08X} ({error.code_name})" if code is not None else str(error)


def dump(master, position: int, progress: Callable[[Iterable, int], Iterable] = lambda it, total: it):
    """Every readable entry of the drive at `position` (in PreOp) as the file's records, and the notes on what could
    not be read. `progress` wraps the objects' iteration (e.g. in a progress bar), given their number."""
    records, notes = [], []
    indices = master.sdo_object_list(position)
    for index in progress(indices, len(indices)):
        try:
            obj = master.sdo_object_description(position, index)
        except _native.EtherCatError as e:
            notes.append(f"0x{index:04X}: no description ({_abort_text(e)}), skipped")
            continue
        for subindex in range(obj["max_subindex"] + 1):
            where = f"0x{index:04X}:{subindex:02X}"
            try:
                entry = master.sdo_entry_description(position, index, subindex)
            except _native.SdoAbortError as e:
                # Records and arrays may leave subindices out; a VAR has only 0.
                if subindex:
                    notes.append(f"{where}: not described ({_abort_text(e)}), skipped")
                continue
            if not _readable(entry["access"]):
                notes.append(f"{where} {entry['name']}: not readable, skipped")
                continue
            try:
                data = master.sdo_read(position, index, subindex)
            except _native.SdoAbortError as e:
                notes.append(f"{where} {entry['name']}: read refused ({_abort_text(e)}), skipped")
                continue
            records.append(
                {
                    "index": _Hex(index),
                    "subindex": subindex,
                    "object": obj["name"],
                    "name": entry["name"],
                    "type": _native.data_type_name(entry["data_type"]),
                    "access": _native.access_names(entry["access"]),
                    "value": decode(data, entry["data_type"]),
                }
            )
    return records, notes


def write_file(path: str, drive: dict, records: list[dict]) -> None:
    """Writes the dump file: the drive it came from, then the records."""
    document = {"format": FILE_FORMAT, "drive": drive, "objects": records}
    text = yaml.safe_dump(document, sort_keys=False, allow_unicode=True, width=120, default_flow_style=None)
    Path(path).write_text(text)


def read_file(path: str) -> list[dict]:
    """The records of a dump file; ValueError naming the file and what is wrong with it."""
    try:
        document = yaml.safe_load(Path(path).read_text())
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark
        raise ValueError(f"{path}, line {mark.line + 1}, column {mark.column + 1}: {e.problem}") from None
    except OSError as e:
        raise ValueError(f"{path}: {e.strerror}") from None
    if not isinstance(document, dict) or not isinstance(document.get("objects"), list):
        raise ValueError(f"{path}: not an akd-sdo dump (a map with a list 'objects'; make one with akd-sdo LINK dump)")
    records = document["objects"]
    for n, record in enumerate(records):
        if not isinstance(record, dict) or not {"index", "subindex", "value"} <= record.keys():
            raise ValueError(f"{path}: objects[{n}] must be a map with index, subindex and value, got {record!r}")
        index, subindex = record["index"], record["subindex"]
        if not (isinstance(index, int) and 0 <= index <= 0xFFFF and isinstance(subindex, int) and 0 <= subindex <= 255):
            raise ValueError(f"{path}: objects[{n}] index must be 0..0xFFFF and subindex 0..255")
    return records


@dataclass
class Write:
    """One SDO write of a restore: what it writes and, for a value the file holds, what the drive held."""

    index: int
    subindex: int
    name: str
    data: bytes
    value: object
    before: object = None
    step: bool = False
    """A step of the order (a count set to 0 first, a count written back) rather than a value that changes."""

    @property
    def where(self) -> str:
        return f"0x{self.index:04X}:{self.subindex:02X}"


@dataclass
class Plan:
    """What a restore does: the writes in order, the entries already as in the file, and the notes on skips and
    values that cannot be encoded."""

    writes: list[Write] = field(default_factory=list)
    unchanged: int = 0
    skipped: list[str] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)


def plan(master, position: int, records: list[dict]) -> Plan:
    """The restore of `records` onto the drive at `position` (in PreOp), in the order the module's doc gives."""
    result = Plan()
    listed = set(master.sdo_object_list(position))
    changes: dict[tuple[int, int], Write] = {}
    same: dict[tuple[int, int], Write] = {}
    described: dict[tuple[int, int], dict] = {}
    for record in records:
        index, subindex, value = record["index"], record["subindex"], record["value"]
        where = f"0x{index:04X}:{subindex:02X}"
        if index not in listed:
            result.skipped.append(f"{where} {record.get('name', '')}: the drive has no such object, skipped")
            continue
        try:
            entry = master.sdo_entry_description(position, index, subindex)
        except _native.SdoAbortError as e:
            result.skipped.append(f"{where}: the drive does not describe it ({_abort_text(e)}), skipped")
            continue
        described[index, subindex] = entry
        if not _writable(entry["access"]):
            result.skipped.append(f"{where} {entry['name']}: read-only, skipped")
            continue
        try:
            data = encode(value, entry["data_type"], (entry["bit_length"] + 7) // 8)
        except ValueError as e:
            result.refused.append(f"{where} {entry['name']}: {e}")
            continue
        current = master.sdo_read(position, index, subindex)
        write = Write(index, subindex, entry["name"], data, value, decode(current, entry["data_type"]))
        if current == data:
            result.unchanged += 1
            same[index, subindex] = replace(write, step=True)
            continue
        changes[index, subindex] = write
    for index in _native.OBJECTS_WRITTEN_WHOLE:
        if any(k[0] == index for k in changes):
            changes |= {k: w for k, w in same.items() if k[0] == index}

    pdo_changes = sorted(k for k in changes if _native.is_pdo_mapping(k[0]) or k[0] in _native.PDO_ASSIGNMENTS)
    if pdo_changes:
        count_of = {}
        for index in {*_native.PDO_ASSIGNMENTS, *(i for i, _ in pdo_changes)}:
            final = changes.pop((index, 0), None)
            if final is None and (index, 0) in described:
                # A count the file leaves as it is still goes to 0 first and back after.
                data = master.sdo_read(position, index, 0)
                final = Write(index, 0, described[index, 0]["name"], data, data[0], step=True)
            if final is not None:
                count_of[index] = final
        zero = {i: Write(i, 0, w.name, b"\0", 0, step=True) for i, w in count_of.items()}
        result.writes += [zero[i] for i in _native.PDO_ASSIGNMENTS if i in zero]
        for index in sorted({i for i, _ in pdo_changes if _native.is_pdo_mapping(i)}):
            result.writes += [zero[index]] if index in zero else []
            result.writes += [changes.pop(k) for k in sorted(changes) if k[0] == index]
            result.writes += [count_of[index]] if index in count_of else []
        for index in _native.PDO_ASSIGNMENTS:
            result.writes += [changes.pop(k) for k in sorted(changes) if k[0] == index]
            result.writes += [count_of[index]] if index in count_of else []
    result.writes += [changes[k] for k in sorted(changes)]
    return result


def execute(master, position: int, writes: list[Write]) -> list[tuple[Write, str]]:
    """Writes each of `writes` in order; gives the refused ones, each with a line saying why, having gone on past
    every one."""
    refused = []
    for write in writes:
        try:
            master.sdo_write(position, write.index, write.subindex, write.data)
        except _native.SdoAbortError as e:
            refused.append((write, f"{write.where} {write.name} <- {write.value!r}: {_abort_text(e)}"))
    return refused
