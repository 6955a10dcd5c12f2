"""Several AKDs on one EtherCAT line as one Bus: one master, one cycle thread, an Axis per drive with its own mode.
A fault on one drive quick-stops the others in the same cycle (fault_reaction "all", as an arm needs).

    .venv/bin/python examples/bus_of_drives.py
"""

import time

from akd_ros import Bus, DriveConfig, Limits

drives = [
    DriveConfig(slave=0, name="shoulder", mode="interpolated_position", limits=Limits(max_velocity=3.0)),
    DriveConfig(slave=1, name="elbow", mode="profile_velocity"),
    DriveConfig(slave=2, name="wrist", mode="profile_torque"),
]
# Three virtual AKDs that count only frames lost on the line as missed (see axis_profile_position.py).
with Bus("sim:3?missed=lost", drives, period=0.001, fault_reaction="all") as bus:
    bus.enable()  # every drive at once; a BusRequestError names each one that refused and why
    shoulder = bus["shoulder"].state().position
    for step in range(1, 101):  # interpolated position: a set-point every cycle or so, here every 5 ms
        bus["shoulder"].command_position(shoulder + 0.2 * step / 100)
        time.sleep(0.005)
    bus["elbow"].command_velocity(-1.0)  # rad/s
    bus["wrist"].command_torque(0.02)  # N·m
    time.sleep(0.5)
    for name, state in bus.states().items():
        print(f"{name}: {state.state}, {state.position:+.3f} rad, velocity {state.velocity:+.3f} rad/s")

    bus.simulator.inject_fault(2, "F439")  # the wrist's drive faults: following error
    time.sleep(0.1)
    for fault in bus["wrist"].fault_events():
        print("wrist:", fault.describe())
    print({name: str(state.state) for name, state in bus.states().items()})  # the others are in Quick stop active
