"""What firmware 01-20 means for our master and node. The DS402 scaling objects (0x608F, 0x6091, 0x6092) as our
master reads them and the Axis uses them: the drive's scale of each position object its mapping carries is checked
against the joint's counts_per_revolution at the start, and a drive set up in another scale is refused with what to
change. CiA 402's cyclic synchronous velocity and torque (9, 10), which the AKD does not offer, are refused with why
and with the AKD's mode that does that."""

from __future__ import annotations

import struct

import pytest

from akd_ros import Axis, CommandError, Units, _native, params

REV = 2**20


@pytest.fixture
def master():
    m = _native.Master("sim?pace=immediate")
    m.scan()
    m.request_state("preop")
    yield m
    m.close()


def test_the_master_reads_the_scaling_objects_and_names_each_position_objects_scale(master):
    s = master.position_scaling(0)
    assert (s.encoder_resolution, s.gear_ratio, s.feed_constant) == ((REV, 1), (1, 1), (1, 1))
    # The virtual AKD's SDO information names FBUS.PARAM05, whose bit 4 is clear: 0x6064/0x607A follow the UNIT
    # parameters, which no DS402 object tells.
    assert s.ds402_scaling is False
    assert s.counts_per_revolution == {(0x6063, 0): REV, (0x60C1, 1): REV, (0x6064, 0): None, (0x607A, 0): None}
    master.sdo_write(0, 0x3E05, 0, struct.pack("<I", 0x10))
    master.sdo_write(0, 0x6092, 1, struct.pack("<I", 36000))
    master.sdo_write(0, 0x6091, 1, struct.pack("<I", 10))
    master.sdo_write(0, 0x608F, 1, struct.pack("<I", 1 << 16))
    s = master.position_scaling(0)
    assert s.ds402_scaling is True
    assert s.counts_per_revolution == {(0x6063, 0): 65536, (0x60C1, 1): 65536, (0x6064, 0): 3600, (0x607A, 0): 3600}


def test_an_axis_in_the_drives_scale_starts_and_keeps_what_it_read():
    with Axis("sim?missed=lost&pace=immediate") as axis:
        assert axis.drive_scaling.counts_per_revolution[(0x6063, 0)] == axis.units.counts_per_revolution == REV


def test_an_axis_whose_counts_per_revolution_differ_from_the_drives_is_refused_with_what_to_change():
    # The default mapping carries 0x60C1:01, counted in 0x608F's 2^20 increments per revolution (and 0x6064, whose
    # scale the UNIT parameters set with DS402 scaling off: not told, not judged).
    with pytest.raises(CommandError) as refused:
        Axis("sim?missed=lost&pace=immediate", units=Units(counts_per_revolution=4096))
    message = str(refused.value)
    assert "counts_per_revolution is 4096, but the drive counts 1048576 per motor revolution" in message
    assert "in 0x60C1:01 (0x608F = 1048576/1" in message and "0x6064" not in message
    assert "256 times off" in message


@pytest.mark.parametrize(("mode", "instead"), [("cyclic_synchronous_velocity", 3), ("cyclic_synchronous_torque", 4)])
def test_modes_9_and_10_are_refused_with_why_and_the_akds_own_mode(mode, instead):
    values = {spec.name: spec.default for spec in params.SCHEMA} | {"mode": mode}
    with pytest.raises(params.ParameterError) as refused:
        params.settings(values)
    assert f"got '{mode}': the AKD offers no mode {'9' if instead == 3 else '10'}" in str(refused.value)
    assert f"({instead}), which takes" in str(refused.value)
    with Axis("sim?missed=lost&pace=immediate") as axis, pytest.raises(CommandError, match=f"{mode}.*AKD offers no"):
        axis.set_mode(mode)
