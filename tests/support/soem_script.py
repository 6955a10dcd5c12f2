"""Source text of pysoem helpers that the SOEM test and bench scripts begin with.

The scripts run in another network namespace as `python -c`, so the helpers travel as text.
"""

SOEM_HELPERS = r'''
import json, struct, sys, time
import pysoem


def open_master(iface):
    """Opens SOEM on `iface`, finds the slaves (config_init reads their SII and requests PreOp)
    and waits for PreOp, which the drive takes a few ms to reach, as the real one does."""
    # A 2-core machine shared with compilers: give each frame 20 ms instead of SOEM's 2 ms.
    pysoem.settings.timeouts.ret = 20000
    master = pysoem.Master()
    master.open(iface)
    found = master.config_init()
    preop = master.state_check(pysoem.PREOP_STATE, 3_000_000) == pysoem.PREOP_STATE
    return master, found, preop


def session(iface, body):
    """Opens SOEM on `iface` (`open_master`), runs `body(master, report)` with the report of what it found, takes the
    slaves back to Init, closes the master and prints the report as JSON (names read as Latin-1), its last line."""
    report = {}
    master, report["found"], report["preop"] = open_master(iface)
    try:
        body(master, report)
        master.state = pysoem.INIT_STATE
        master.write_state()
    finally:
        master.close()
    print(json.dumps(report, default=lambda raw: raw.decode("latin-1")))


def select_fixed_mappings(master, position):
    """AKD_FACTS 6: the fixed mappings 0x1701/0x1B01, chosen by writing both assignments."""
    slave = master.slaves[position]
    for assign, pdo in ((0x1C12, 0x1701), (0x1C13, 0x1B01)):
        slave.sdo_write(assign, 0, bytes([0]))
        slave.sdo_write(assign, 1, struct.pack("<H", pdo))
        slave.sdo_write(assign, 0, bytes([1]))


def select_flexible_mappings(master, position):
    """AKD_FACTS 6: counts cleared, entries with sub 0 = 0 first and the count last, then the
    assignment; 24-bit PDOs padded to even lengths with the AKD's dummy objects."""
    slave = master.slaves[position]
    for assign, pdo, entries in ((0x1C12, 0x1600, (0x60400010, 0x60600008, 0x00020008)),
                                 (0x1C13, 0x1A00, (0x60410010, 0x60610008, 0x20020108))):
        slave.sdo_write(assign, 0, bytes([0]))
        slave.sdo_write(pdo, 0, bytes([0]))
        for sub, entry in enumerate(entries, start=1):
            slave.sdo_write(pdo, sub, struct.pack("<I", entry))
        slave.sdo_write(pdo, 0, bytes([len(entries)]))
        slave.sdo_write(assign, 1, struct.pack("<H", pdo))
        slave.sdo_write(assign, 0, bytes([1]))


def use_mappings(master, select):
    """Makes config_map call `select(master, position)` for every slave in PreOp."""
    for slave in master.slaves:
        slave.config_func = lambda position: select(master, position)


def reach_safeop(master):
    """Requests SafeOp for all slaves; True when they all reach it within 1 s."""
    master.state = pysoem.SAFEOP_STATE
    master.write_state()
    return master.state_check(pysoem.SAFEOP_STATE, 1_000_000) == pysoem.SAFEOP_STATE


def reach_op(master):
    """Requests Op and keeps process data flowing (the drive needs it) until all are in Op."""
    master.state = pysoem.OP_STATE
    master.write_state()
    for _ in range(300):
        master.send_processdata()
        master.receive_processdata(20000)
        if master.state_check(pysoem.OP_STATE, 5000) == pysoem.OP_STATE:
            return True
    return False
'''
