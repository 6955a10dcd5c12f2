"""The master (akd_ros._native.Master) against in-process virtual AKDs ("sim", "sim:N").

Each test drives the real master code against the real virtual AKD: scan, AL states, SDO of
every size, SDO information, every fixed mapping, process data with the expected working
counter, and errors by name.

The virtual AKDs judge missed frames by the frames the line lost (`?missed=lost`): nothing here is about this shared
host's scheduling, so a cycle it runs late must not fault them (F125) as it would a real drive.
"""

from __future__ import annotations

import time

import pytest

from akd_ros import _native

VENDOR_KOLLMORGEN = 0x6A
PRODUCT_AKD = 0x00414B44
RX_FIXED = [0x1701, 0x1702, 0x1720, 0x1721, 0x1722, 0x1723, 0x1724]
TX_FIXED = [0x1B01, 0x1B20, 0x1B21, 0x1B22, 0x1B23, 0x1B24, 0x1B25]


def raw_al_request(master, position: int, state: int) -> None:
    """Writes AL control behind the master's state handling. The AKD's ESC refuses a new AL
    control write until its firmware took the last one (WKC 0), so retry for a while."""
    deadline = time.monotonic() + 5
    while True:
        try:
            master.write_register(position, 0x0120, state.to_bytes(2, "little"))
            return
        except _native.WorkingCounterError:
            assert time.monotonic() < deadline, "AL control stayed locked"


def wait_for(condition, what: str, timeout: float = 5.0):
    deadline = time.monotonic() + timeout
    while not (value := condition()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
    return value


@pytest.fixture
def master():
    with _native.Master("sim?missed=lost") as m:
        m.scan()
        yield m


def test_scan_finds_the_virtual_akd():
    with _native.Master("sim:2?missed=lost") as m:
        slaves = m.scan()
        assert m.slave_count == 2
        for position, slave in enumerate(slaves):
            assert slave["position"] == position
            assert slave["station_address"] == 0x1001 + position
            assert slave["vendor_id"] == VENDOR_KOLLMORGEN
            assert slave["product_code"] == PRODUCT_AKD
            assert slave["revision"] == 2
            assert slave["name"] == "AKD EtherCAT Drive (CoE)"
            assert slave["model"] == "AKD-P00606-NBCC-E000"
            assert slave["firmware"] == "01-20-00-003"
            assert slave["al_state"] == "Init"
            assert (slave["al_status_code"], slave["al_status_code_name"]) == (0, "no error")
            assert (slave["found_al_state"], slave["found_al_status_code"]) == ("Init", 0)
            assert slave["mailbox_protocols"] & 0x04, "CoE"


def test_scan_reports_the_state_and_error_it_found_before_resetting(master):
    master.request_state("op")
    (slave,) = master.scan()
    assert (slave["found_al_state"], slave["al_state"]) == ("Op", "Init")
    # Init -> Op directly is refused by the AKD with 0x0011; the scan reports it as found.
    master.write_register(0, 0x0120, b"\x08\x00")
    deadline = time.monotonic() + 2.0
    while master.al_status(0)[1] == 0 and time.monotonic() < deadline:
        time.sleep(0.001)
    (slave,) = master.scan()
    assert slave["found_al_status_code"] == 0x0011
    assert slave["found_al_status_code_name"] == "invalid requested state change"
    assert slave["al_status_code"] == 0


def test_walks_init_preop_safeop_op_and_back(master):
    for state, name in [("preop", "PreOp"), ("safeop", "SafeOp"), ("op", "Op"), ("init", "Init")]:
        master.request_state(state)
        assert master.al_status(0) == (name, 0, "no error")


@pytest.mark.parametrize("rx,tx", [(rx, 0x1B01) for rx in RX_FIXED] + [(0x1701, tx) for tx in TX_FIXED[1:]])
def test_every_fixed_mapping_exchanges_process_data(master, rx, tx):
    master.request_state("preop")
    master.configure_pdo(0, rx, tx)
    # Both assignments are written, as the real drive requires.
    assert master.sdo_read(0, 0x1C12, 1) == rx.to_bytes(2, "little")
    assert master.sdo_read(0, 0x1C13, 1) == tx.to_bytes(2, "little")
    master.request_state("op")
    assert master.expected_wkc == 3
    assert master.exchange() == 3
    # Inputs come from the drive: its statusword (first in 0x1B01's neighbours or found by
    # SDO) is what the cycle brought back somewhere in the input image.
    statusword = master.sdo_read(0, 0x6041, 0)
    assert master.exchange() == 3
    assert statusword in master.inputs(0)


def test_outputs_reach_the_drive_and_inputs_come_from_it(master):
    master.request_state("op")  # default mapping 0x1701 / 0x1B01
    outputs = bytearray(master.outputs(0))
    assert len(outputs) == 6
    # 0x1701: position command 0x60C1:01 (4), controlword (2).
    outputs[0:4] = (123456).to_bytes(4, "little", signed=True)
    outputs[4:6] = (0x0006).to_bytes(2, "little")
    master.set_outputs(0, bytes(outputs))
    assert master.exchange() == 3
    assert master.sdo_read(0, 0x6040, 0) == (0x0006).to_bytes(2, "little")
    assert master.sdo_read(0, 0x60C1, 1) == (123456).to_bytes(4, "little", signed=True)
    # 0x1B01: position (4), statusword (2).
    assert master.exchange() == 3
    assert master.inputs(0)[4:6] == master.sdo_read(0, 0x6041, 0)


def test_process_data_sent_now_and_taken_later_with_sdo_between(master):
    master.request_state("op")
    with pytest.raises(_native.ConfigError, match="no cyclic frame is on its way: send one with send_process_data"):
        master.receive_process_data()
    master.set_outputs(0, (7).to_bytes(4, "little", signed=True) + (0x0006).to_bytes(2, "little"))
    master.send_process_data()
    for call in (master.send_process_data, master.exchange, lambda: _native.Cycle(master, 0.001)):
        with pytest.raises(_native.ConfigError, match="already on its way: take its return with receive_process_data"):
            call()
    # The SDO's frames meet the cyclic frame's return on their way and keep it for its receive.
    assert master.sdo_read(0, 0x60C1, 1) == (7).to_bytes(4, "little", signed=True)
    assert master.receive_process_data() == 3
    assert master.stats()["lost_frames"] == 0
    assert master.exchange() == 3


def test_flexible_mapping(master):
    master.request_state("preop")
    master.configure_pdo(0, [[0x60400010, 0x607A0020]], [[0x60410010, 0x60640020]])
    assert master.sdo_read(0, 0x1600, 1) == (0x60400010).to_bytes(4, "little")
    master.request_state("op")
    assert master.exchange() == 3
    assert len(master.outputs(0)) == 6 and len(master.inputs(0)) == 6


def test_odd_flexible_mapping_is_refused_with_the_reason(master):
    master.request_state("preop")
    with pytest.raises(_native.PdoError, match="odd"):
        master.configure_pdo(0, [[0x60400010, 0x60600008]], 0x1B01)


def test_sdo_round_trips_of_every_size(master):
    master.request_state("preop")
    for index, data in [(0x6060, b"\x08"), (0x6040, b"\x0f\x00"), (0x607A, (-5).to_bytes(4, "little", signed=True))]:
        master.sdo_write(0, index, 0, data)
        assert master.sdo_read(0, index, 0) == data
    # Strings longer than 4 bytes go in normal (not expedited) transfers.
    assert master.sdo_read(0, 0x1009, 0) == b"AKD-P00606-NBCC-E000"
    assert master.sdo_read(0, 0x100A, 0) == b"01-20-00-003"


def test_sdo_abort_by_name(master):
    master.request_state("preop")
    with pytest.raises(_native.SdoAbortError) as info:
        master.sdo_read(0, 0x1234, 0)
    error = info.value
    assert (error.index, error.subindex, error.code) == (0x1234, 0, 0x06020000)
    assert error.code_name == "object does not exist in the object dictionary"
    assert "object does not exist" in str(error)


def test_sdo_information(master):
    master.request_state("preop")
    objects = master.sdo_object_list(0)
    assert {0x1000, 0x1018, 0x6040, 0x6041} <= set(objects)
    identity = master.sdo_object_description(0, 0x1018)
    assert identity["index"] == 0x1018 and identity["max_subindex"] >= 4
    entry = master.sdo_entry_description(0, 0x6041, 0)
    assert (entry["data_type"], entry["bit_length"]) == (0x0006, 16)


def test_refused_state_change_is_named(master):
    raw_al_request(master, 0, 0x08)  # Init -> Op: not allowed
    state, code, name = wait_for(lambda: (s := master.al_status(0))[1] and s, "the AL status code")
    assert (state, code, name) == ("Init", 0x0011, "invalid requested state change")
    master.request_state("preop")  # acknowledges and goes on
    with pytest.raises(_native.AlStateError) as info:
        master.request_state("bootstrap")
    assert (info.value.code, info.value.code_name) == (0x0011, "invalid requested state change")


def test_wrong_wkc_is_counted_and_raised():
    with _native.Master("sim:2?missed=lost") as m:
        m.scan()
        m.request_state("op")
        assert m.exchange() == 6
        raw_al_request(m, 1, 0x01)
        wait_for(lambda: m.al_status(1)[0] == "Init", "slave 1 in Init")
        with pytest.raises(_native.WorkingCounterError) as info:
            m.exchange()
        assert (info.value.expected, info.value.got) == (6, 3)
        assert m.stats()["wkc_errors"] == 1


def test_bad_arguments_raise_clear_errors(master):
    with pytest.raises(_native.ConfigError, match="allowed: init, preop"):
        master.request_state("running")
    with pytest.raises(_native.ConfigError, match="no slave at position 5"):
        master.sdo_read(5, 0x1000, 0)
    with pytest.raises(_native.PdoError, match="not a fixed RxPDO"):
        master.configure_pdo(0, 0x1B01, 0x1B01)
    with pytest.raises(_native.ConfigError, match="link"):
        _native.Master("udp:/nowhere")
    with pytest.raises(_native.LinkError, match="nosuchif0"):
        _native.Master("nosuchif0")
    master.close()
    with pytest.raises(_native.ConfigError, match="closed"):
        master.scan()


def test_distributed_clocks():
    with _native.Master("sim:2?missed=lost") as m:
        m.scan()
        m.request_state("preop")
        m.configure_dc(2_000_000)
        assert m.sdo_read(0, 0x60C2, 1) == b"\x02"
        assert m.read_register(1, 0x0981, 1) == b"\x03"
        m.request_state("op")
        assert m.exchange() == 6
        assert m.stats()["wkc_errors"] == 0


def test_cycle_time_without_dc(master):
    master.request_state("preop")
    master.set_cycle_time(0, 500_000)
    assert (master.sdo_read(0, 0x60C2, 1), master.sdo_read(0, 0x60C2, 2)) == (
        b"\x05",
        (-4).to_bytes(1, "little", signed=True),
    )
    with pytest.raises(_native.ConfigError, match="250000"):
        master.set_cycle_time(0, 100_000)


def test_a_second_thread_gets_an_error_instead_of_waiting(master):
    import threading

    worker = threading.Thread(target=master.request_state, args=("op",))
    worker.start()
    refused = []
    while worker.is_alive():
        try:
            master.stats()
        except _native.ConfigError as error:
            refused.append(str(error))
    worker.join()
    assert refused and "in use by another thread" in refused[0]
    assert master.al_status(0)[0] == "Op"
