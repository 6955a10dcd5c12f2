"""The master over real links: EtherCAT-over-UDP to `akd-sim` in another process, and raw
Ethernet (AF_PACKET) over a veth pair to `akd-sim --iface` in a network namespace."""

from __future__ import annotations

import pytest

from akd_ros import _native
from support.netns import akd_sim_in_netns, akd_sim_udp, entered_netns


def _bring_to_op_and_exchange(master: _native.Master, count: int) -> None:
    slaves = master.scan()
    assert len(slaves) == count
    assert all(s["vendor_id"] == 0x6A and s["product_code"] == 0x00414B44 for s in slaves)
    master.request_state("preop")
    assert master.sdo_read(count - 1, 0x1018, 2) == (0x00414B44).to_bytes(4, "little")
    master.request_state("op")
    for _ in range(20):
        assert master.exchange() == 3 * count
    stats = master.stats()
    assert (stats["lost_frames"], stats["wkc_errors"]) == (0, 0)


def test_master_over_udp_to_akd_sim(udp_port):
    with akd_sim_udp(udp_port, count=2), _native.Master(f"udp://127.0.0.1:{udp_port}", timeout=0.5) as master:
        assert master.link == f"udp://127.0.0.1:{udp_port}"
        _bring_to_op_and_exchange(master, 2)


def test_master_over_udp_without_simulator_times_out(udp_port):
    with (
        _native.Master(f"udp://127.0.0.1:{udp_port}", timeout=0.05) as master,
        pytest.raises((_native.TimeoutError, _native.LinkError)),
    ):
        master.scan()


@pytest.mark.parametrize("count", [1, 2])
def test_master_over_veth_with_af_packet(veth, count):
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=count):
        with entered_netns(veth.ns_master):
            master = _native.Master(veth.if_master, timeout=0.5)
        try:
            assert master.link == veth.if_master
            _bring_to_op_and_exchange(master, count)
        finally:
            master.close()
