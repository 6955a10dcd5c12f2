"""Round trip of one cyclic frame, this master beside SOEM (pysoem) and KickCAT, on the same wire.

Not a test: timing depends on the machine and its load, so only the ratios to SOEM measured in this
run count. One veth pair between two network namespaces, one `akd-sim --iface` process serving the
virtual AKDs on one end for every run of every master; each master runs in its own process in the
other namespace, brings the drives to Op with the fixed mappings 0x1701/0x1B01 and runs a paced loop
(sleep to an absolute deadline, then one cyclic exchange) at each rate. Runs alternate A/B/C/A/B/C,
so a change in the machine's load falls on every master alike.

Besides the frame SOEM and KickCAT send (one LRW), this master is also measured with the frame its
cycle thread sends, `akd_ros+watch`: the LRW and the reads of AL status and mailbox status that
supervise the bus (`Master.set_supervision`: two broadcast reads while every drive is alike), in
the same process right after; both again on the link `IFACE?busy_poll=200` (`+busy_poll`): the
master busy-polls the socket for the returning frame for up to 200 µs before it sleeps, where the
default sleeps at once; and, on each link, the node's own loop, a `Cycle` thread (` Cycle` rows):
native pacing, the supervised frame and the drives' state machines, its round trips from its
exchange histogram and its CPU from the thread's schedstat.

`+pipelined` rows send each cycle's frame and take its return at the next wake-up instead of
waiting for it (`Master.send_process_data` / `receive_process_data`; the Cycle's `realtime=RealTime(pipelined=True)`),
on the default link: they wait for no round trip, so they have none to show, only their CPU.
`SOEM+pipelined` is SOEM used the same way (`send_processdata` now, `receive_processdata` at the
next wake-up), to show what the pattern gives any master.

akd-sim runs `--busy-poll` on the last CPU under the normal scheduler, and every master on the
other CPUs: a real AKD's ESC answers in hardware as the frame passes, and a server woken by each
frame would add the scheduler's wake-up (tens of µs on a virtual machine, the same for every
master) to every round trip. `--sim-wakes` runs akd-sim as the tests do (SCHED_FIFO, woken by
each frame, no CPU of its own) instead.

Per master, drive count and rate: the round trip of the cyclic exchange (the call, as a Python
program makes it, from before the frame is sent to after its return is taken: `Master.exchange()`,
pysoem `send_processdata` + `receive_processdata`, kickcat `Bus.process_data`) at p50, p99, p99.9
and max, pooled over the runs; CPU per cycle (the loop thread's CPU time over the measured
cycles, pacing included, which is the same code for every master) and, of it, the exchange's own
(the thread's CPU time across the call alone: the master's cost), with the ratios to SOEM; and
the pacing's, the rest (the sleep and the loop: on a virtual machine, the wake-up from a halted
vCPU costs tens of µs of CPU, the same for every master). The CPU clock is read around every
call, and what reading it costs (measured before each run) is taken off every figure. Every
cycle's working counter is checked; a wrong one, a frame lost, or a master that does not reach Op
leaves a figure unmeasured and the script exits with status 1. Needs root (network namespaces).

    sudo .venv/bin/python bench/roundtrip.py [--quick] [--json PATH] [--rounds 3] [--cycles 5000]
        [--counts 1,4] [--rates 1000,4000] [--baseline DIR]

`--baseline DIR` adds one more master: the akd_ros package in DIR (a copy of an earlier build,
`akd_ros/` with its `_native` extension), to measure a change before and after in one run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from figures import histogram_us, machine

from support.kickcat_script import KICKCAT_HELPERS
from support.netns import (
    SIM_PRIORITY,
    akd_sim_in_netns,
    netns_unavailable_reason,
    run_python_in_netns,
    veth_pair,
)
from support.soem_script import SOEM_HELPERS

# How long every master waits for a frame: long enough that a frame the loaded machine delays is
# measured as a slow round trip rather than counted lost.
FRAME_TIMEOUT_S = 0.1

# How long this master busy-polls in its `+busy_poll` rows, µs: past the p99.9 of a round trip to
# a busy-polling akd-sim here, and within a 4 kHz cycle.
BUSY_POLL_US = 200

# What the rows of this master's Cycle thread are named after the link's.
CYCLE = " Cycle"

# The paced loop every master runs, the same text for all: `exchange()` is one cyclic round trip
# that returns whether the working counter was the expected one.
PACED_LOOP = (
    f"TIMEOUT_S = {FRAME_TIMEOUT_S}\nBUSY_POLL_US = {BUSY_POLL_US}\nCYCLE = {CYCLE!r}\n"
    + r"""
import gc, json, os, sys, time

# The CPUs measure() leaves to the masters, the same for every one.
if os.environ.get("ROUNDTRIP_CPUS"):
    os.sched_setaffinity(0, {int(cpu) for cpu in os.environ["ROUNDTRIP_CPUS"].split(",")})


# The thread CPU, ns, that reading the CPU clock around a call costs by itself (a system call: the
# vDSO has no thread CPU clock), taken off every master's figures alike.
# The least of three passes of `samples` reads, each as the loop makes them around a call.
def probe_cost(clock, cpu, samples=2000):
    def nothing():
        return True

    def one_pass():
        total = 0
        for _ in range(samples):
            before = cpu()
            start = clock()
            nothing()
            clock() - start
            total += cpu() - before
        return total / samples

    return min(one_pass() for _ in range(3))


def paced(exchange, rate, cycles, warmup):
    period = 1_000_000_000 // rate
    clock, cpu = time.perf_counter_ns, time.thread_time_ns
    times, bad, late, in_exchange = [0] * cycles, 0, 0, 0
    gc.disable()
    probe = probe_cost(clock, cpu)
    deadline = clock() + period
    for n in range(warmup + cycles):
        if n == warmup:
            cpu_start = cpu()
            in_exchange = 0
        now = clock()
        if deadline > now:
            time.sleep((deadline - now) / 1e9)
        elif now - deadline > period:
            late += n >= warmup
            deadline = now
        before = cpu()
        start = clock()
        good = exchange()
        took = clock() - start
        in_exchange += cpu() - before
        if n >= warmup:
            times[n - warmup] = took
            bad += not good
        deadline += period
    total = cpu() - cpu_start - cycles * probe
    gc.enable()
    return {"times_ns": times, "cpu_ns": total, "exchange_cpu_ns": in_exchange - cycles * probe,
            "probe_ns": probe, "bad_wkc": bad, "late": late}


def run_rates(exchange, rates, cycles, warmup):
    return {str(rate): paced(exchange, rate, cycles, warmup) for rate in rates}


# A pipelined loop: each call takes the return of the frame the last one sent (`receive`, whether
# it was good) and sends the next (`send`); none waits for a round trip, so none is reported.
def run_pipelined(receive, send, rates, cycles, warmup):
    send()

    def exchange():
        good = receive()
        send()
        return good

    by_rate = run_rates(exchange, rates, cycles, warmup)
    receive()
    return {rate: {**run, "waits": False} for rate, run in by_rate.items()}
"""
)

AKD_ROS_SCRIPT = (
    PACED_LOOP
    # The bench's own helpers, after whichever akd_ros (this one's, a --baseline's) comes first.
    + f"sys.path.append({str(Path(__file__).resolve().parent)!r})\n"
    + r"""
iface, rates, cycles, warmup = sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
from akd_ros import _native
from cycle_jitter import cycle_thread_cpu_ns


# The plain and the supervised frame's variants on `link`; the drives found, the frames lost.
def measure_link(link, prefix):
    with _native.Master(link, timeout=TIMEOUT_S) as master:
        found = len(master.scan())
        master.request_state("preop")
        master.request_state("op")
        expected = master.expected_wkc

        # Whether `call` (a whole exchange, or taking a return) gave the expected working counter.
        def good(call):
            try:
                return call() == expected
            except _native.EtherCatError:
                return False

        def exchange():
            return good(master.exchange)

        variants = {prefix: run_rates(exchange, rates, cycles, warmup)}
        # Sent at one wake-up, taken at the next (not in a --baseline build without the halves).
        if not prefix and hasattr(master, "send_process_data"):

            def receive():
                return good(master.receive_process_data)

            variants["+pipelined"] = run_pipelined(receive, master.send_process_data, rates, cycles, warmup)
        # The frame a Cycle sends: the LRW and the reads of AL status and mailbox status (not in
        # a --baseline build older than Master.set_supervision).
        if hasattr(master, "set_supervision"):
            master.set_supervision(True)
            variants[prefix + "+watch"] = run_rates(exchange, rates, cycles, warmup)
            if not all(w["answered"] and w["al_state"] == "Op" for w in master.watch()):
                raise RuntimeError(f"akd_ros: supervision did not see every drive in Op: {master.watch()}")
        lost = master.stats()["lost_frames"]
        master.request_state("init")
    if hasattr(_native, "Cycle"):
        variants[prefix + CYCLE] = {str(rate): cycle_thread(link, rate, cycles, warmup) for rate in rates}
        if not prefix and "+pipelined" in variants:
            variants["+pipelined" + CYCLE] = {
                str(rate): cycle_thread(link, rate, cycles, warmup, pipelined=True) for rate in rates
            }
    return found, lost, variants


# The node's own loop on `link`: a Cycle thread, paced natively on the normal scheduler as the
# Python loops are, its frame supervised (the +watch frame). Its round trips are the exchange
# histogram's 1 µs buckets (upper edges) over the measured cycles, its CPU the thread's own;
# `pipelined`, it waits for no round trip and its exchange histogram holds its send and receive.
def cycle_thread(link, rate, cycles, warmup, pipelined=False):
    with _native.Master(link, timeout=TIMEOUT_S) as master:
        master.scan()
        master.request_state("preop")
        master.request_state("op")
        cycle = _native.Cycle(master, 1 / rate, realtime=_native.RealTime(pipelined=pipelined))
        try:
            while cycle.snapshot()["cycle"] < warmup:
                time.sleep(0.01)
            before, stats0, cpu0 = dict(cycle.histograms()["exchange"]), cycle.stats(), cycle_thread_cpu_ns()
            while cycle.snapshot()["cycle"] < stats0["cycles"] + cycles:
                time.sleep(0.01)
            after, stats1, cpu1 = dict(cycle.histograms()["exchange"]), cycle.stats(), cycle_thread_cpu_ns()
        finally:
            cycle.stop()
        if any(not w["answered"] or w["al_state"] != "Op" for w in master.watch()):
            raise RuntimeError(f"akd_ros: the Cycle's supervision did not see every drive in Op: {master.watch()}")
        master.request_state("init")
    times = [edge for edge, count in sorted(after.items()) for _ in range(count - before.get(edge, 0))]
    counted = ("lost_frames", "wkc_errors")
    return {"times_ns": times, "cpu_ns": (cpu1 - cpu0) * len(times) / (stats1["cycles"] - stats0["cycles"]),
            "exchange_cpu_ns": None, "bad_wkc": sum(stats1[k] - stats0[k] for k in counted),
            "late": stats1["overruns"] - stats0["overruns"], "waits": not pipelined}


found, lost, variants = measure_link(iface, "")
# Not in a --baseline build older than the busy poll.
if getattr(_native.parse_link(iface), "busy_poll_us", None) is not None:
    _, lost_busy, busy = measure_link(f"{iface}?busy_poll={BUSY_POLL_US}", "+busy_poll")
    variants.update(busy)
    lost += lost_busy
print(json.dumps({"found": found, "lost": lost, "variants": variants,
                  "version": _native.__file__}))
"""
)

SOEM_SCRIPT = (
    SOEM_HELPERS
    + PACED_LOOP
    + r"""
iface, rates, cycles, warmup = sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
master, found, _ = open_master(iface)
try:
    use_mappings(master, select_fixed_mappings)
    master.config_map()
    if not (reach_safeop(master) and reach_op(master)):
        raise RuntimeError("SOEM: the drives did not reach Op")
    expected = master.expected_wkc

    def exchange():
        master.send_processdata()
        return master.receive_processdata(int(TIMEOUT_S * 1e6)) == expected

    report = {"": run_rates(exchange, rates, cycles, warmup)}

    def receive():
        return master.receive_processdata(int(TIMEOUT_S * 1e6)) == expected

    report["+pipelined"] = run_pipelined(receive, master.send_processdata, rates, cycles, warmup)
    master.state = pysoem.INIT_STATE
    master.write_state()
finally:
    master.close()
print(json.dumps({"found": found, "lost": None, "variants": report, "version": pysoem.__version__}))
"""
)

KICKCAT_SCRIPT = (
    KICKCAT_HELPERS
    + PACED_LOOP
    + r"""
iface, rates, cycles, warmup = sys.argv[1], json.loads(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
from importlib.metadata import version

link, bus, _, _ = open_bus(iface, attempts=5)
link.set_timeout(TIMEOUT_S)
slaves = bus.slaves()
select_fixed_mappings(bus, slaves)
bus.create_mapping()
bus.request_state(State.SAFE_OP)
bus.wait_for_state(State.SAFE_OP, 2.0)
for slave in slaves:
    slave.set_output_bytes(struct.pack("<iH", 0, 0x0006))
bus.process_data()
bus.request_state(State.OPERATIONAL)
bus.wait_for_state(State.OPERATIONAL, 2.0, bus.process_data)


def exchange():
    # process_data raises when a datagram's working counter is not the expected one.
    try:
        bus.process_data()
        return True
    except Exception:
        return False


report = run_rates(exchange, rates, cycles, warmup)
bus.request_state(State.INIT)
print(json.dumps({"found": len(slaves), "lost": None, "variants": {"": report}, "version": version("kickcat")}))
"""
)

SOEM = "SOEM"
CONTENDERS = {"akd_ros": AKD_ROS_SCRIPT, SOEM: SOEM_SCRIPT, "KickCAT": KICKCAT_SCRIPT}


def percentile(sorted_ns: list[int], q: float) -> float:
    """The q-quantile of sorted samples (nearest rank), in µs."""
    return sorted_ns[min(len(sorted_ns) - 1, int(q * len(sorted_ns)))] / 1000


def summarise(runs: list[dict]) -> dict:
    """Pools the runs of one master at one count and rate into the reported figures (µs); a loop that
    waits for no round trip (pipelined) has none."""
    times = sorted(t for run in runs for t in run["times_ns"])
    cycles = len(times)
    native = any(run["exchange_cpu_ns"] is None for run in runs)
    waits = all(run.get("waits", True) for run in runs)
    cpu = sum(run["cpu_ns"] for run in runs)
    exchange_cpu = None if native else sum(run["exchange_cpu_ns"] for run in runs)

    def round_trip(q: float) -> float | None:
        return percentile(times, q) if waits else None

    return {
        "runs": len(runs),
        "cycles": cycles,
        "waits": waits,
        "p50_us": round_trip(0.5),
        "p99_us": round_trip(0.99),
        "p99.9_us": round_trip(0.999),
        "max_us": times[-1] / 1000 if waits else None,
        "cpu_per_cycle_us": cpu / cycles / 1000,
        # Not for a Cycle thread: its pacing is native and its exchange's CPU not its own to read.
        "exchange_cpu_us": None if native else exchange_cpu / cycles / 1000,
        "pacing_cpu_us": None if native else (cpu - exchange_cpu) / cycles / 1000,
        "bad_wkc": sum(run["bad_wkc"] for run in runs),
        "late": sum(run["late"] for run in runs),
        # Each run's own median: how far the machine's load moved the figures from run to run.
        "run_p50_us": [percentile(sorted(run["times_ns"]), 0.5) for run in runs] if waits else None,
    }


FIGURES = ("p50_us", "p99_us", "p99.9_us", "max_us", "cpu_per_cycle_us", "exchange_cpu_us")
# Shown beside the figures, never as a ratio: the loop's own CPU, the same code for every master.
SHOWN = (*FIGURES, "pacing_cpu_us")


def run_master(net, name: str, script: str, rates: list[int], cycles: int, warmup: int, cpus: list[int]) -> dict:
    """One run of one master in the master namespace, on `cpus` (all, if empty); its report, or {"error": ...}."""
    timeout = 60 + 2 * len(rates) * (cycles + warmup) * 2 / min(rates)
    env = {**os.environ, "ROUNDTRIP_CPUS": ",".join(map(str, cpus))}
    try:
        result = run_python_in_netns(
            net.ns_master,
            script,
            args=[net.if_master, json.dumps(rates), str(cycles), str(warmup)],
            timeout=timeout,
            env=env,
        )
    except subprocess.TimeoutExpired as error:  # a hung master: its figures are unmeasured, the others count
        return {"error": f"{name}: {type(error).__name__}: {error}"}
    if result.returncode != 0:
        last = (result.stderr.strip() or result.stdout.strip()).splitlines()[-1:] or ["no output"]
        return {"error": f"{name} exited with status {result.returncode}: {last[0]}"}
    try:
        return json.loads(result.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        return {"error": f"{name} printed no report: {result.stdout.strip()[-200:]!r}"}


# More cycles than this share without their round trip (a frame lost, a wrong working counter)
# and the master's figures do not count: it was not exchanging process data with every drive.
BAD_SHARE = 0.001
# A Cycle counts a frame not back within its period lost, as its drives see the next cycle's
# frame instead: on the normal scheduler of a loaded machine some are, and that is its figure.
# Past this share it did not hold the line.
CYCLE_BAD_SHARE = 0.01


def cpu_split(sim_wakes: bool) -> tuple[int | None, list[int]]:
    """akd-sim's CPU and the masters': a busy-polling akd-sim takes the last CPU this process may
    use, the masters the others; with `sim_wakes`, none for akd-sim and all for the masters."""
    cpus = sorted(os.sched_getaffinity(0))
    if sim_wakes or len(cpus) < 2:
        return None, []
    return cpus[-1], cpus[:-1]


def measure(args, contenders: dict[str, str]) -> tuple[dict, list[dict], list[str]]:
    """Every count: one akd-sim, `rounds` rounds of every master in turn. Returns the figures
    {count: {rate: {master: summary}}}, the round trips' distributions at the highest rate (one per
    count, as bench/figures.py's) and the problems met."""
    results, distributions, problems = {}, [], []
    for count in args.counts:
        runs: dict[str, list[dict]] = {}
        with (
            veth_pair() as net,
            akd_sim_in_netns(net.ns_sim, net.if_sim, count=count, cpu=args.sim_cpu, busy_poll=args.sim_cpu is not None),
        ):
            for round_ in range(args.rounds):
                for name, script in contenders.items():
                    report = run_master(net, name, script, args.rates, args.cycles, args.warmup, args.master_cpus)
                    if "error" in report:
                        problems.append(f"{count} AKD(s), round {round_ + 1}: {report['error']}")
                        continue
                    if report["found"] != count:
                        problems.append(f"{count} AKD(s): {name} found {report['found']} slaves")
                        continue
                    for suffix, by_rate in report["variants"].items():
                        runs.setdefault(name + suffix, []).append(by_rate)
                    print(
                        f"  {count} AKD(s) round {round_ + 1}: {name} ({report['version']})",
                        file=sys.stderr,
                        flush=True,
                    )
        results[count] = {}
        for rate in args.rates:
            row, series = {}, {}
            for name, reports in runs.items():
                pooled = [r[str(rate)] for r in reports]
                summary = summarise(pooled)
                if summary["waits"]:
                    series[name] = histogram_us((t for run in pooled for t in run["times_ns"]), 1000)
                if summary["bad_wkc"] > (CYCLE_BAD_SHARE if name.endswith(CYCLE) else BAD_SHARE) * summary["cycles"]:
                    problems.append(
                        f"{count} AKD(s) at {rate} Hz: {name} had {summary['bad_wkc']} of {summary['cycles']} "
                        "cycles without a good return"
                    )
                else:
                    row[name] = summary
            results[count][rate] = row
            if rate == max(args.rates):
                title = f"round trip over veth, {count} AKD{'s' if count > 1 else ''} at {rate} Hz"
                distributions.append({"title": title, "series": series})
    return results, distributions, problems


def ratios(row: dict) -> dict:
    """Each master's figures over SOEM's, where both were measured."""
    soem = row.get(SOEM)
    if soem is None:
        return {}
    return {
        name: {f: s[f] / soem[f] for f in FIGURES if s[f] is not None and soem[f]}
        for name, s in row.items()
        if name != SOEM
    }


def flat_rows(results: dict) -> list[dict]:
    """One row per count, rate and master: the figures in µs and each as a ratio to SOEM's."""
    rows = []
    for count, by_rate in results.items():
        for rate, row in by_rate.items():
            rel = ratios(row)
            for name, s in row.items():
                cells = {"AKDs": count, "loop Hz": rate, "master": name}
                cells |= {f: None if s[f] is None else round(s[f], 1) for f in SHOWN}
                cells["lost or bad wkc"] = s["bad_wkc"]
                cells |= {f"{f.removesuffix('_us')} x SOEM": round(r, 2) for f, r in rel.get(name, {}).items()}
                rows.append(cells)
    return rows


def print_table(results: dict) -> None:
    head = f"{'AKDs':>4} {'rate':>6} {'master':<14}" + "".join(f"{f.removesuffix('_us'):>16}" for f in SHOWN)
    print(head + f"{'bad':>6}{'late':>6}   (us; x SOEM)")
    for count, by_rate in results.items():
        for rate, row in by_rate.items():
            rel = ratios(row)
            for name, s in row.items():
                cells = []
                for f in SHOWN:
                    r = rel.get(name, {}).get(f)
                    value = "-" if s[f] is None else f"{s[f]:.1f}"
                    cells.append(f"{value:>8}" + (f" ({r:4.2f}x)" if r is not None else " " * 8))
                print(
                    f"{count:>4} {rate:>6} {name:<14}"
                    + "".join(f"{c:>16}" for c in cells)
                    + f"{s['bad_wkc']:>6}{s['late']:>6}"
                )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 rounds of 2000 cycles (about 3 minutes)")
    parser.add_argument("--rounds", type=int, default=3, help="runs of each master, alternating (default 3)")
    parser.add_argument("--cycles", type=int, default=5000, help="measured cycles per run and rate (default 5000)")
    parser.add_argument("--warmup", type=int, default=200, help="cycles before the measured ones (default 200)")
    parser.add_argument("--counts", default="1,4", help="virtual AKDs on the line, comma-separated (default 1,4)")
    parser.add_argument("--rates", default="1000,4000", help="loop rates in Hz, comma-separated (default 1000,4000)")
    parser.add_argument(
        "--masters", default=",".join(CONTENDERS), help=f"masters to run (default {','.join(CONTENDERS)})"
    )
    parser.add_argument("--baseline", type=Path, help="a directory holding another build's akd_ros/ to measure too")
    parser.add_argument(
        "--sim-wakes",
        action="store_true",
        help="akd-sim under SCHED_FIFO, woken by each frame, as the tests run it (default: --busy-poll on a CPU of "
        "its own, answering as the drive's ESC does)",
    )
    parser.add_argument("--json", type=Path, help="also write the figures to this file as JSON")
    args = parser.parse_args()
    if args.quick:
        args.rounds, args.cycles = 2, 2000
    try:
        args.counts = [int(c) for c in args.counts.split(",")]
        args.rates = [int(r) for r in args.rates.split(",")]
    except ValueError:
        parser.error("--counts and --rates take comma-separated whole numbers, e.g. 1,4 and 1000,4000")
    if min(args.counts) < 1 or min(args.rates) < 1 or args.rounds < 1 or args.cycles < 1:
        parser.error("--counts, --rates, --rounds and --cycles must be at least 1")
    # A stopped run still removes its namespaces and stops its akd-sim (the context managers).
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    reason = netns_unavailable_reason()
    if reason:
        print(f"roundtrip: {reason} (run as root)", file=sys.stderr)
        return 2
    chosen = args.masters.split(",")
    unknown = [name for name in chosen if name not in CONTENDERS]
    if unknown or SOEM not in chosen:
        parser.error(
            f"--masters: {', '.join(unknown) or 'SOEM missing'}; choose from {', '.join(CONTENDERS)}, SOEM always"
        )
    contenders = {name: CONTENDERS[name] for name in chosen}
    if args.baseline:
        if not (args.baseline / "akd_ros").is_dir():
            parser.error(f"--baseline {args.baseline}: no akd_ros/ package in it")
        # First on sys.path, ahead of the working directory `python -c` puts there.
        first = f"import sys; sys.path.insert(0, {str(args.baseline.resolve())!r})\n"
        contenders = {"baseline": first + AKD_ROS_SCRIPT, **contenders}

    args.sim_cpu, args.master_cpus = cpu_split(args.sim_wakes)
    settings = {
        "rounds": args.rounds,
        "cycles_per_run": args.cycles,
        "warmup_cycles": args.warmup,
        "counts": args.counts,
        "rates_hz": args.rates,
        "masters": list(contenders),
        "link": "veth pair between two network namespaces, one akd-sim --iface process per count",
        "akd_sim": (
            f"woken by each frame, SCHED_FIFO {SIM_PRIORITY}, any CPU"
            if args.sim_cpu is None
            else f"--busy-poll on CPU {args.sim_cpu}, normal scheduler; masters on CPU(s) "
            + ",".join(map(str, args.master_cpus))
        ),
        "busy_poll_us": BUSY_POLL_US,
        "mappings": "fixed 0x1701/0x1B01 (6 bytes each way per AKD)",
        "frame_timeout_s": FRAME_TIMEOUT_S,
        "pacing": "Python loop, sleep to an absolute deadline on the monotonic clock, normal scheduler",
    }
    info = machine() | {"python": platform.python_version()}
    print(f"machine: {info['uname']}; {info['cpu']}, {info['cores']} cores; Python {info['python']}")
    print(f"settings: {json.dumps(settings)}")
    started, load_before = time.monotonic(), os.getloadavg()
    results, distributions, problems = measure(args, contenders)
    duration, load_after = time.monotonic() - started, os.getloadavg()
    info["load_average_1min"] = {"before": load_before[0], "after": load_after[0]}
    print_table(results)
    print(f"duration: {duration:.0f} s; load average (1 min) {load_before[0]:.1f} before, {load_after[0]:.1f} after")
    # Every master at every count and rate must have its figures, or the run does not count.
    for count in args.counts:
        for rate in args.rates:
            missing = [name for name in contenders if name not in results[count][rate]]
            if missing:
                problems.append(f"{count} AKD(s) at {rate} Hz: no figures for {', '.join(missing)}")
    for problem in problems:
        print(f"unmeasured: {problem}", file=sys.stderr)
    if args.json:
        document = {
            "machine": info,
            "settings": settings,
            "duration_s": duration,
            "results": {
                str(count): {str(rate): {"figures": row, "ratio_to_soem": ratios(row)} for rate, row in by_rate.items()}
                for count, by_rate in results.items()
            },
            "problems": problems,
            "distributions": distributions,
            # bench/run.py's table and list of what could not be measured.
            "rows": flat_rows(results),
            "not_measured": problems,
        }
        args.json.write_text(json.dumps(document, indent=2) + "\n")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
