"""The drive knowledge the extension exposes (modes, default mapping, mapping rules, entry syntax, data types, inputs
read by the mapping), checked against what the virtual AKD does and says about itself, not against a second copy."""

from __future__ import annotations

import pytest
from akd_ros._native import Ds402State

from akd_ros import _native
from support.waiting import wait_for

MODES = {m.name: m for m in _native.MODES_OF_OPERATION}


def entry_type(master, index: int, subindex: int = 0) -> tuple[str, int]:
    """The kind and byte size of an object as the drive's SDO information describes it."""
    entry = master.sdo_entry_description(0, index, subindex)
    return _native.data_type_kind(entry["data_type"]), (entry["bit_length"] + 7) // 8


def encode(kinds: dict, address: tuple[int, int], value: int) -> bytes:
    kind, size = kinds[address]
    return value.to_bytes(size, "little", signed=kind == "signed_integer")


def decode(kinds: dict, address: tuple[int, int], data: bytes) -> int:
    kind, size = kinds[address]
    assert kind in ("signed_integer", "unsigned_integer") and len(data) == size, (address, kind, data)
    return int.from_bytes(data, "little", signed=kind == "signed_integer")


# The inputs Cycle.drive_inputs reads, by the objects they come from.
INPUT_OBJECTS = {
    "statusword": 0x6041,
    "mode_display": 0x6061,
    "position_actual": 0x6064,
    "velocity_actual": 0x606C,
    "torque_actual": 0x6077,
    "following_error": 0x60F4,
    "digital_inputs": 0x60FD,
}
COMMAND_OBJECTS = {address for m in MODES.values() for address in m.command_objects}


@pytest.fixture
def drive():
    """A virtual AKD in Op with the default mapping, cycled every ms, and the SDO types of the objects used."""
    master = _native.Master("sim")
    master.scan()
    master.request_state("preop")
    addresses = {*((index, 0) for index in INPUT_OBJECTS.values()), *COMMAND_OBJECTS, (0x6040, 0)}
    kinds = {address: entry_type(master, *address) for address in addresses}
    master.configure_pdo(0, *_native.DEFAULT_MAPPING)
    master.request_state("op")
    cycle = _native.Cycle(master, 0.001)
    try:
        yield cycle, kinds
    finally:
        cycle.stop()
        master.close()


def test_the_virtual_akd_takes_every_mode_of_the_table_and_no_other_code() -> None:
    with _native.Master("sim") as master:
        master.scan()
        master.request_state("preop")
        for mode in MODES.values():
            master.sdo_write(0, 0x6060, 0, mode.code.to_bytes(1, "little", signed=True))
        others = sorted(set(range(-128, 128)) - {m.code for m in MODES.values()})
        for code in others[::16]:
            with pytest.raises(_native.SdoAbortError):
                master.sdo_write(0, 0x6060, 0, code.to_bytes(1, "little", signed=True))


def test_every_mode_is_shown_by_the_drive_and_its_command_is_mapped_by_the_default_mapping(drive) -> None:
    cycle, kinds = drive
    outputs = {(index, sub) for index, sub, _, _ in cycle.mapping(0)["outputs"]}
    for mode in MODES.values():
        assert not mode.command_objects or mode.command_objects[0] in outputs, mode.name
        cycle.set_mode(0, mode.code)
        shown = wait_for(f"mode display {mode.code}", lambda code=mode.code: cycle.drive_inputs(0).mode_display == code)
        assert shown and decode(kinds, (0x6061, 0), cycle.sdo_read(0, 0x6061, 0)) == mode.code
        for address in mode.command_objects:
            # A command may be negative (backwards, or braking): its object is a signed integer on the drive.
            assert kinds[address][0] == "signed_integer", (mode.name, address)
        assert (mode.command is None) == (not mode.command_objects), mode.name


def test_the_handshake_bits_start_profile_position_and_homing_in_the_cycle_threads_handshake(drive) -> None:
    cycle, kinds = drive
    for name in ("profile_position", "homing"):
        mode = MODES[name]
        cycle.set_mode(0, mode.code)
        cycle.enable(0)
        cycle.wait_state(0, Ds402State.OPERATION_ENABLED)
        if mode.command_objects:
            target = cycle.drive_inputs(0).position_actual - 50_000
            cycle.set_object(0, *mode.command_objects[0], encode(kinds, mode.command_objects[0], target))
        cycle.start_setpoint(0, mode.handshake_controlword)
        cycle.wait_setpoint(0, timeout=5.0)
        if name == "profile_position":
            wait_for("the profile move", lambda target=target: abs(cycle.drive_inputs(0).position_actual - target) < 20)
        else:
            wait_for("homing to zero the position", lambda: abs(cycle.drive_inputs(0).position_actual) < 2)
        cycle.disable(0)
        cycle.wait_state(0, Ds402State.SWITCH_ON_DISABLED)
    # The modes that follow their command every cycle have no handshake to start them.
    assert {m.name for m in MODES.values() if m.handshake_controlword is not None} == {"profile_position", "homing"}


def test_decoded_inputs_agree_with_sdo_reads_of_the_same_objects(drive) -> None:
    cycle, kinds = drive
    torque = MODES["profile_torque"]
    cycle.set_mode(0, torque.code)
    cycle.enable(0)
    cycle.wait_state(0, Ds402State.OPERATION_ENABLED)
    # A negative torque: the shaft accelerates backwards, so position and velocity go negative and fall each cycle.
    cycle.set_object(0, *torque.command_objects[0], encode(kinds, torque.command_objects[0], -200))
    wait_for("a negative position", lambda: cycle.drive_inputs(0).position_actual < -10_000)
    for _ in range(5):
        before = cycle.drive_inputs(0)
        read = {name: decode(kinds, (index, 0), cycle.sdo_read(0, index, 0)) for name, index in INPUT_OBJECTS.items()}
        after = cycle.drive_inputs(0)
        for name, value in read.items():
            low, high = sorted((getattr(before, name), getattr(after, name)))
            # Falling values lie between the cycles before and after the read; steady ones are equal.
            assert low <= value <= high, (name, getattr(before, name), value, getattr(after, name))
    assert after.torque_actual == -200 and after.velocity_actual < 0 and after.mode_display == torque.code
    assert after.cycle > before.cycle and after.fresh
    cycle.disable(0)
    cycle.wait_state(0, Ds402State.SWITCH_ON_DISABLED)


def test_a_fixed_mapping_reads_the_internal_position_and_lacks_the_rest() -> None:
    with _native.Master("sim") as master:
        master.scan()
        master.request_state("preop")
        master.configure_pdo(0, 0x1701, 0x1B01)
        master.request_state("op")
        with _native.Cycle(master, 0.001) as cycle:
            inputs = wait_for("a cycle", lambda: (i := cycle.drive_inputs(0)).cycle > 0 and i)
            assert inputs.position_actual == int.from_bytes(cycle.sdo_read(0, 0x6063, 0), "little", signed=True)
            assert (
                inputs.velocity_actual,
                inputs.torque_actual,
                inputs.following_error,
                inputs.mode_display,
                inputs.digital_inputs,
            ) == (None,) * 5
            assert inputs.statusword is not None


MAPPINGS = [
    _native.DEFAULT_MAPPING,
    (0x1724, 0x1B26),
    (0x1799, 0x1B01),
    (0x1701, 0x1701),
    ([[0x60400010, 0x60C10120]], [[0x60410010, 0x60640020]]),
    ([[0x60400010, 0x12345620]], [[0x60410010]]),
    ([[0x60400010, 0x60600008]], [[0x60410010]]),
    ([[0x60400010, 0x607A0020, 0x60FF0020]], [[0x60410010]]),
    ([[0x60410010]], [[0x60410010]]),
    ([[0x607A0020, 0x60FF0020]] * 3, [[0x60410010]]),
    ("no mapping", [[0x60410010]]),
]


@pytest.mark.parametrize("rx, tx", MAPPINGS)
def test_check_mapping_refuses_what_the_virtual_akd_refuses_with_the_same_reason(rx, tx) -> None:
    def outcome(attempt) -> str | None:
        try:
            attempt()
        except _native.PdoError as e:
            return f"PdoError: {e}"
        except _native.ConfigError as e:
            return f"ConfigError: {e}"
        return None

    with _native.Master("sim") as master:
        master.scan()
        master.request_state("preop")
        on_the_drive = outcome(lambda: master.configure_pdo(0, rx, tx))
    assert outcome(lambda: _native.check_mapping(rx, tx)) == on_the_drive


def test_entries_written_as_text_configure_the_drive_with_those_words() -> None:
    def text(word: int) -> str:
        return f"0x{word >> 16:04X}:{word >> 8 & 0xFF:02X}/{word & 0xFF}"

    texts = [" ".join(text(word) for word in pdo) for pdo in _native.DEFAULT_MAPPING[0]]
    rx = [[_native.parse_pdo_entry(word) for word in text.split()] for text in texts]
    with _native.Master("sim") as master:
        master.scan()
        master.request_state("preop")
        master.configure_pdo(0, rx, _native.DEFAULT_MAPPING[1])
        for i, pdo in enumerate(rx):
            written = [int.from_bytes(master.sdo_read(0, 0x1600 + i, sub + 1), "little") for sub in range(len(pdo))]
            assert written == pdo == _native.DEFAULT_MAPPING[0][i]
    assert _native.parse_pdo_entry("60c1:1/32") == _native.parse_pdo_entry("0x60C1:0x01/32")
    for bad in ("6040-16", "0x6040:00", "0x6040:100/16", "0x6040:00/100"):
        with pytest.raises(ValueError, match=f"'{bad}' is not INDEX:SUB/BITS"):
            _native.parse_pdo_entry(bad)


def test_data_types_read_the_drives_values_as_its_sdo_information_names_them() -> None:
    with _native.Master("sim") as master:
        master.scan()
        master.request_state("preop")
        for index, subindex, name, kind in (
            (0x6041, 0, "UNSIGNED16", "unsigned_integer"),
            (0x6064, 0, "INTEGER32", "signed_integer"),
            (0x1008, 0, "VISIBLE_STRING", "visible_string"),
        ):
            data_type = master.sdo_entry_description(0, index, subindex)["data_type"]
            assert (_native.data_type_name(data_type), _native.data_type_kind(data_type)) == (name, kind)
    assert _native.data_type_kind(0x0008) == "real" and _native.data_type_kind(0x0023) == "other"
    assert _native.data_type_name(0x7777) == "unknown data type"


def test_encoded_values_are_what_the_drive_takes_and_reads_back() -> None:
    with _native.Master("sim") as master:
        master.scan()
        master.request_state("preop")
        for index, subindex, value in (
            (0x607A, 0, -(2**31)),
            (0x60FF, 0, 2**31 - 1),
            (0x6071, 0, -1000),
            (0x6060, 0, MODES["homing"].code),
            (0x6081, 0, 2**32 - 1),
            (0x60C1, 1, -5),
        ):
            data = _native.encode_value(index, subindex, value)
            kinds = {(index, subindex): entry_type(master, index, subindex)}
            assert len(data) == kinds[(index, subindex)][1], hex(index)
            master.sdo_write(0, index, subindex, data)
            assert decode(kinds, (index, subindex), master.sdo_read(0, index, subindex)) == value
    with pytest.raises(ValueError, match=r"40000 is outside the range of 0x6071:00 Target torque \(INTEGER16"):
        _native.encode_value(0x6071, 0, 40_000)
    with pytest.raises(ValueError, match="0x1234:05 is no object the AKD maps"):
        _native.encode_value(0x1234, 5, 0)


def test_ds402_states_name_what_the_sequencer_reaches(drive) -> None:
    cycle, _ = drive
    for request, state in (
        (cycle.enable, Ds402State.OPERATION_ENABLED),
        (cycle.quick_stop, Ds402State.QUICK_STOP_ACTIVE),
        (cycle.disable, Ds402State.SWITCH_ON_DISABLED),
    ):
        request(0)
        cycle.wait_state(0, state)
        assert state in _native.DS402_STATES
        assert Ds402State.from_statusword(cycle.drive_inputs(0).statusword) == state
    assert Ds402State.from_statusword(0x0005) is None


def test_a_state_prints_as_cia_402_writes_it_and_messages_spell_it_as_one_word() -> None:
    state = Ds402State.FAULT_REACTION_ACTIVE
    assert (str(state), state.snake_name, state.is_fault) == ("Fault reaction active", "fault_reaction_active", True)
    assert [s for s in _native.DS402_STATES if s.is_fault] == [Ds402State.FAULT_REACTION_ACTIVE, Ds402State.FAULT]
    assert Ds402State.message_name(None) == "unknown"
    assert f"{Ds402State.OPERATION_ENABLED}" == "Operation enabled" != Ds402State.OPERATION_ENABLED
