"""Source text of kickcat helpers that the KickCAT test and bench scripts begin with.

The scripts run in another network namespace as `python -c`, so the helpers travel as text.
"""

KICKCAT_HELPERS = r'''
import json, struct, sys, time
import kickcat
from kickcat import State
from kickcat.mailbox.request import MessageStatus


def open_bus(iface, attempts=3):
    """Opens kickcat on `iface` and runs Bus.init; returns (link, bus, attempts taken, errors).

    kickcat's default frame time-out is 2 ms; a 2-core machine sometimes delays a reply longer,
    and Bus.init gives up at the first late reply (seen on a quiet fresh-clone CI run too: "Error
    while fetching eeprom data"). Without a redundancy interface every broadcast exchange (one per
    SII read in Bus.init) lasts the whole time-out, so it is kept short and Bus.init is tried
    again from a new link, up to `attempts` times.
    """
    errors = []
    for attempt in range(1, attempts + 1):
        link = kickcat.create_link(iface, "")
        link.set_timeout(0.01)
        bus = kickcat.Bus(link)
        try:
            # Detects the slaves, reads their SII, sets the mailboxes up from it, requests PreOp
            # and waits; the argument is the process-data watchdog written to the slaves (2 s: a
            # slow cycle in a loaded test must not trip it).
            bus.init(2.0)
            return link, bus, attempt, errors
        except RuntimeError as error:
            errors.append(str(error))
            del bus, link
    raise RuntimeError(f"Bus.init failed {attempts} times: {errors}")


def start(iface):
    """Opens kickcat on `iface` (`open_bus`); returns the link (which must outlive the bus), the bus, its slaves and a
    report of what it found."""
    report = {}
    link, bus, report["init_attempts"], report["init_errors"] = open_bus(iface)
    slaves = bus.slaves()
    report["found"] = len(slaves)
    report["state_after_init"] = [str(bus.get_state(s)) for s in slaves]
    return link, bus, slaves, report


def run_cycles(bus, set_outputs, cycles=100):
    """`cycles` of process data, `set_outputs()` before each, 1 ms apart; kickcat's process_data raises on any
    datagram whose working counter is not the one it expects. Returns the errors and the first one's text."""
    errors, first = 0, None
    for cycle in range(cycles):
        set_outputs(cycle)
        try:
            bus.process_data()
        except Exception as error:
            errors += 1
            first = first or str(error)
        time.sleep(0.001)
    return errors, first


def write_sdo(bus, slave, index, subindex, data):
    """Downloads `data` to the slave's object index:subindex, serving the mailboxes until done."""
    message = slave.mailbox.write_sdo(index, subindex, False, data, 1.0)
    deadline = time.monotonic() + 2.0
    while message.status() == MessageStatus.RUNNING and time.monotonic() < deadline:
        bus.process_mailboxes()
    if message.status() != MessageStatus.SUCCESS:
        raise RuntimeError(f"SDO write 0x{index:04X}:{subindex:02X} failed: {message.status()}")


def select_fixed_mappings(bus, slaves):
    """AKD_FACTS 6: the fixed mappings 0x1701/0x1B01, written to both assignment objects."""
    for slave in slaves:
        for assign, pdo in ((0x1C12, 0x1701), (0x1C13, 0x1B01)):
            write_sdo(bus, slave, assign, 0, bytes([0]))
            write_sdo(bus, slave, assign, 1, struct.pack("<H", pdo))
            write_sdo(bus, slave, assign, 0, bytes([1]))
'''
