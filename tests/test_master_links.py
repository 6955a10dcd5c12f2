"""The master over real links: EtherCAT-over-UDP to `akd-sim` in another process, and raw
Ethernet (AF_PACKET) over a veth pair to `akd-sim --iface` in a network namespace."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time

import pytest

from akd_ros import _native
from support.netns import akd_sim_in_netns, akd_sim_udp, console_script, entered_netns, netns_argv, realtime


def _bring_to_op_and_exchange(master: _native.Master, count: int) -> None:
    slaves = master.scan()
    assert len(slaves) == count
    assert all(s["vendor_id"] == 0x6A and s["product_code"] == 0x00414B44 for s in slaves)
    master.request_state("preop")
    assert master.sdo_read(count - 1, 0x1018, 2) == (0x00414B44).to_bytes(4, "little")
    master.request_state("op")
    for _ in range(20):
        assert master.exchange() == 3 * count
    # Sent now and taken later, as a pipelined cycle does, with mailbox frames between: their
    # exchanges keep the cyclic frame's return for it, none is taken for another's.
    for _ in range(5):
        master.send_process_data()
        assert master.sdo_read(0, 0x1018, 1) == (0x6A).to_bytes(4, "little")
        assert master.receive_process_data() == 3 * count
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


@pytest.mark.parametrize(("busy_poll_us", "sim_busy_polls"), [(300, True), (1, False)])
def test_master_busy_polling_over_veth(veth, busy_poll_us, sim_busy_polls):
    """The master busy-polls for each returning frame: against a busy-polling akd-sim (on a CPU of
    its own where there are two) the frames come back within the poll; against one woken by each
    frame, a poll of 1 µs ends before any frame is back and the master sleeps until it comes. Either
    way every frame of a bring-up, mailbox traffic and exchanges comes back, none taken for another's."""
    cpu = max(os.sched_getaffinity(0)) if sim_busy_polls else None
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=2, cpu=cpu, busy_poll=sim_busy_polls) as sim:
        with entered_netns(veth.ns_master):
            master = _native.Master(f"{veth.if_master}?busy_poll={busy_poll_us}", timeout=0.5)
        try:
            assert master.link == veth.if_master
            _bring_to_op_and_exchange(master, 2)
            assert master.sdo_read(0, 0x1018, 1) == (0x6A).to_bytes(4, "little")
        finally:
            master.close()
    assert ("--busy-poll" in sim.args) == sim_busy_polls


def test_akd_sim_loses_a_reply_the_line_went_down_under_and_serves_on(veth):
    """A frame akd-sim takes after the master's end of the line went down cannot go back (the kernel refuses the send):
    lost, as on a real line, and akd-sim serves the frames that come once the line is up again. It exited on it, so a
    test taking a link down could find no simulator when it came back. Made certain by stopping akd-sim (SIGSTOP) while
    the frame waits in its socket and the line goes down."""
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=1) as sim:
        with entered_netns(veth.ns_master):
            master = _native.Master(veth.if_master, timeout=0.2)
        try:
            assert master.scan()
            os.kill(sim.pid, signal.SIGSTOP)
            try:
                with pytest.raises(_native.TimeoutError):
                    master.al_status(0)
                subprocess.run(["ip", "-n", veth.ns_master, "link", "set", veth.if_master, "down"], check=True)
            finally:
                os.kill(sim.pid, signal.SIGCONT)
            time.sleep(0.3)
            assert sim.poll() is None, sim.communicate()
            subprocess.run(["ip", "-n", veth.ns_master, "link", "set", veth.if_master, "up"], check=True)
            deadline = time.monotonic() + 5
            while True:
                try:
                    assert master.al_status(0)[0] == "Init"
                    break
                except (_native.TimeoutError, _native.EtherCatError):
                    assert time.monotonic() < deadline, "akd-sim did not answer once the line was up again"
                    time.sleep(0.05)
        finally:
            master.close()


def _answered_once_resumed(sim: subprocess.Popen, stopped_for: float, call) -> None:
    """Stops akd-sim (SIGSTOP), makes `call` while it is stopped and resumes it (SIGCONT) `stopped_for` s later: the
    frame waits in akd-sim's socket and its reply goes back that late."""
    os.kill(sim.pid, signal.SIGSTOP)
    resume = subprocess.Popen(["sh", "-c", f"sleep {stopped_for}; kill -CONT {sim.pid}"])
    try:
        call()
    finally:
        resume.wait()


def test_akd_sim_counts_the_replies_it_sent_late_because_it_was_not_run(veth):
    """akd-sim says how late its replies went back because it was not run, which tells a frame lost because the
    simulator's host held it (as shared test machines do for milliseconds) from one the master lost: a register read
    answered 200 ms late counts over every bound."""
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=1) as sim:
        with entered_netns(veth.ns_master):
            master = _native.Master(veth.if_master, timeout=1.0)
        try:
            assert master.scan()
            _answered_once_resumed(sim, 0.2, lambda: master.al_status(0))
        finally:
            master.close()
    served = re.search(
        r"akd-sim: served (?P<served>\d+) frames \(0 malformed, 0 lost on the line, 0 unsent\); replies late because "
        r"akd-sim was not run: (?P<over>.*), longest (?P<longest>[\d.]+) ms",
        sim.output_text,
    )
    assert served, sim.output_text
    over = {float(bound): int(count) for count, bound in re.findall(r"(\d+) over ([\d.]+) ms", served["over"])}
    assert list(over) == [0.25, 0.5, 1, 2, 4] and all(count >= 1 for count in over.values()), served[0]
    assert 200 <= float(served["longest"]) < 1000, served[0]


def test_akd_sim_refuses_to_busy_poll_under_a_real_time_policy(veth):
    """A spinning SCHED_FIFO thread is stopped by the kernel 50 ms a second and starves its CPU:
    akd-sim says so and exits 1 without a traceback."""
    argv = netns_argv(veth.ns_sim, [*console_script("akd-sim"), "--iface", veth.if_sim, "--busy-poll"])
    result = subprocess.run(argv, capture_output=True, text=True, timeout=30, preexec_fn=lambda: realtime(10))
    assert result.returncode == 1, result
    assert "Traceback" not in result.stderr
    assert "must run under the normal scheduler, not SCHED_FIFO or SCHED_RR" in result.stderr, result.stderr


def test_akd_sim_busy_poll_needs_an_interface():
    result = subprocess.run(
        [*console_script("akd-sim"), "--udp", "127.0.0.1:1", "--busy-poll"], capture_output=True, text=True, timeout=30
    )
    assert result.returncode == 2 and "--busy-poll needs --iface" in result.stderr, result
