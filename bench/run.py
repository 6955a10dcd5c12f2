"""Runs the benchmark suite end to end and writes bench/RESULTS.md and bench/results.png from that run's figures.

Each section is one script of bench/ run as its own process with --json; its figures (tables, distributions, what
it could not measure, settings, machine, how long it ran) are kept together in bench/results/run.json, its output in
bench/results/SECTION.log, and rendered: the tables into RESULTS.md, the distributions into results.png
(matplotlib, Agg) as tail plots, 1 - CDF on log axes. Nothing in RESULTS.md is typed in: every figure comes from
those files.

    .venv/bin/python bench/run.py [--skip SECTION[,SECTION]] [--render]

Sections, in the order they run (sudo or root: roundtrip's and many's veth pairs, the SCHED_FIFO priorities, perf):
  master_cycle  cost of one cyclic exchange in-process, 1/4/16/64 AKDs, frame size (master_cycle.py)
  roundtrip     this master, SOEM and KickCAT over one veth pair to one akd-sim (roundtrip.py, 3 rounds of 2000)
  jitter        the cycle thread's wake-up latency and period jitter beside cyclictest (cycle_jitter.py)
  python        the cycle's jitter with busy Python threads and SDO traffic, against idle (cycle_jitter.py)
  line_health   the cycle on six virtual AKDs with the line's links and error counters read beside it and without
                (line_health.py)
  cell_devices  the cycle on two virtual AKDs behind an EK1100, an EL1004 and an EL2004, against the two alone
                (cell_devices.py)
  ros           akd_node: command to wire, cycle to /joint_states, CPU; DDS beside Zenoh; issue 25's goals, with
                profiles of what misses one (node_ros.py --profile)
  many          akd_node on 16 and 64 AKDs over veth at 250 µs, a million cycles each, waiting and pipelined
                (node_ros.py --drives)
  io            akd_node's CPU with every joint's ~/io published and without, six joints at 1 kHz (node_io.py)
  live_view     akd_node's CPU with the live view in Foxglove off, on, and on with a client subscribed to every
                channel, six joints at 1 kHz (live_view.py)
  host_noise    config/akd_sim_6axis.yaml's robot following trajectories under stress-ng on every CPU, with and
                without missed=warn and rt.priority: trajectories done, would-be F125, worst stall (host_noise.py,
                2 minutes per variant; --minutes 8 for a full run)

--skip leaves sections out (RESULTS.md says skipped); --again runs the sections it names again and keeps the last
run's others (RESULTS.md says which, and when each section ended); --render writes RESULTS.md and results.png again
from the JSON files of the last run, running nothing. Exit status: 0 when every section that ran measured every figure,
1 when any could not be measured (a script missing, failing, timing out, or saying so), 2 on a bad option.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

from figures import cell, columns_of, machine

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parent
RESULTS = BENCH / "results"
SECTIONS = {
    "master_cycle": (shlex.split("master_cycle.py --counts 1,4,16,64 --cycles 5000"), 120),
    # Three rounds, not --quick's two: each master's CPU per cycle moved by ±0.2 of SOEM's between two-round runs.
    "roundtrip": (shlex.split("roundtrip.py --rounds 3 --cycles 2000"), 450),
    "jitter": (shlex.split("cycle_jitter.py --loads idle --rates 1000,4000 --seconds 4 --rounds 4"), 240),
    "python": (
        shlex.split("cycle_jitter.py --loads idle,busy,sdo --no-cyclictest --rates 4000 --seconds 4 --rounds 4"),
        180,
    ),
    "line_health": (shlex.split("line_health.py --rates 1000,4000 --seconds 4 --rounds 4"), 240),
    "cell_devices": (shlex.split("cell_devices.py --rates 1000,4000 --seconds 4 --rounds 4"), 240),
    "ros": (["node_ros.py", "--profile"], 1200),
    "many": (shlex.split("node_ros.py --drives 16,64 --drive-pipelined"), 2400),
    "io": (["node_io.py"], 300),
    "live_view": (["live_view.py"], 600),
    # Two minutes per variant, two alternating rounds: a shorter run than a quotable one (--minutes 8, about 35 min).
    "host_noise": (shlex.split("host_noise.py --minutes 2 --rounds 2"), 900),
}
"""Each section's script and arguments (--json added), and the seconds it may take before it is ended."""
TITLES = {
    "master_cycle": "Cost per cycle in-process, by drives on the bus",
    "roundtrip": "Round trip over veth: this master, SOEM and KickCAT",
    "jitter": "Cycle thread beside cyclictest",
    "python": "Python's cost on the loop",
    "line_health": "The line's counters read beside the cycle, against not",
    "cell_devices": "Devices beside the drives: the cycle on a cell against the same drives alone",
    "ros": "Through ROS: latencies and the node's CPU, DDS and Zenoh",
    "many": "Through ROS with many drives over veth",
    "io": "The drives' I/O on ROS: the node's CPU with every joint's ~/io and without",
    "live_view": "The live view in Foxglove: the node's CPU with it off, on, and with a client",
    "host_noise": "The six-axis virtual robot with every CPU loaded: F125 with and without missed=warn, rt.priority",
}


def utc_now() -> str:
    """Now, as RESULTS.md dates a run and a section."""
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def run_section(name: str) -> dict:
    """Runs section `name`'s script; gives its JSON, or a record of why there is none."""
    argv, limit = SECTIONS[name]
    script = BENCH / argv[0]
    out = RESULTS / f"{name}.json"
    out.unlink(missing_ok=True)  # a figure of an earlier run is never taken for this one's
    command = [sys.executable, str(script), *argv[1:], "--json", str(out)]
    shown = shlex.join([".venv/bin/python", f"bench/{argv[0]}", *argv[1:], "--json", f"bench/results/{name}.json"])
    if not script.exists():
        return {"status": "missing", "why": f"bench/{argv[0]} missing", "command": shown}
    print(f"run.py: {name}: {shown}", flush=True)
    log = RESULTS / f"{name}.log"
    started = time.monotonic()
    with log.open("w") as output:
        process = subprocess.Popen(command, stdout=output, stderr=subprocess.STDOUT, cwd=ROOT, start_new_session=True)
        try:
            code = process.wait(timeout=limit)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGTERM)
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
            code = None
    seconds = round(time.monotonic() - started, 1)
    date = utc_now()
    record = {"command": shown, "exit": code, "wall_seconds": seconds, "ended": date}
    if out.exists():
        record |= json.loads(out.read_text())
        out.unlink()  # kept in results/run.json with the run's other sections
    if code is None:
        record |= {"status": "failed", "why": f"ended after the {limit} s it may take"}
    elif code != 0 and "tables" not in record and "rows" not in record:
        tail = log.read_text().strip().splitlines()[-3:]
        record |= {"status": "failed", "why": f"exit {code}: " + " / ".join(tail)[:400]}
    else:
        record["status"] = "measured" if code == 0 else "partly measured"
    print(f"run.py: {name}: {record['status']} in {seconds} s", flush=True)
    return record


def markdown_table(rows: list) -> list[str]:
    if not rows:
        return ["(no rows)"]
    if not all(isinstance(r, dict) for r in rows):
        return [f"- {json.dumps(r)}" for r in rows]
    columns = columns_of(rows)
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r.get(c)) for c in columns) + " |" for r in rows]
    return lines


def tables_of(record: dict) -> list[dict]:
    """The tables of a section: its own ("tables"), or a script's top-level "rows" as one table."""
    tables = list(record.get("tables", []))
    if "rows" in record:
        tables.insert(0, {"title": record.get("title", "rows"), "rows": record["rows"]})
    return tables


def render(records: dict, total: dict) -> str:
    lines = [
        "# Benchmark results",
        "",
        f"Written by `{total['command']}` on {total['date']} in {total['seconds']:.0f} s; every figure below comes"
        " from the scripts of that run (their JSON together in `bench/results/run.json`, their output in"
        " `bench/results/SECTION.log`).",
        "",
        "**The machine is shared and noisy**: other jobs ran on its cores during the run, so absolute times"
        " vary from run to run; the ratios, taken against a peer measured in the same run with the contenders"
        " alternating, are the figures to compare.",
        "",
        f"Machine: `{total['machine']['uname']}`, {total['machine']['cpu']}, {total['machine']['cores']} cores;"
        f" load (1/5/15 min) {cell(total['machine']['load'])} at the start, {cell(total['machine_at_end']['load'])}"
        " at the end.",
        "",
        "![distributions](results.png)",
        "",
        "| section | status | ran | command |",
        "|---|---|---|---|",
    ]
    if total.get("again"):
        lines[2:2] = [
            f"Run again on their own ({total['again']['date']}, `{total['again']['command']}`), the other sections"
            f" kept from the run above: {', '.join(total['again']['sections'])}.",
            "",
        ]
    for name, record in records.items():
        ran = f"{record['wall_seconds']} s" if "wall_seconds" in record else ""
        ran += f", ended {record['ended']}" if "ended" in record else ""
        status = record["status"] + (f": {record['why']}" if "why" in record else "")
        lines.append(f"| {name} | {status} | {ran} | `{record.get('command', '')}` |")
    for name, record in records.items():
        lines += ["", f"## {TITLES[name]}", ""]
        if record["status"] == "skipped":
            lines.append("**skipped (--skip)**")
            continue
        if "why" in record:
            lines.append(f"**not measured: {record['why']}**")
            if not tables_of(record):
                continue
        lines.append(
            f"`{record['command']}`, {record.get('seconds', record.get('wall_seconds'))} s; load at its start"
            f" {cell(record.get('machine', {}).get('load'))}."
        )
        if settings := record.get("settings"):
            lines += ["", "Settings: " + ", ".join(f"{k} {cell(v)}" for k, v in settings.items()) + "."]
        for table in tables_of(record):
            lines += ["", f"**{table['title']}**", "", *markdown_table(table["rows"])]
        if record.get("not_measured"):
            lines += ["", "Not measured:", *(f"- {what}" for what in record["not_measured"])]
        if record.get("notes"):
            lines += ["", *(f"- {note}" for note in record["notes"])]
    return "\n".join(lines) + "\n"


def plot(records: dict, path: Path) -> None:
    """Every distribution of the run as 1 - CDF (the share of samples above a value) on log axes, one panel each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(name, d) for name, r in records.items() for d in r.get("distributions", []) if d["series"]]
    if not panels:
        return
    columns = 2
    rows = -(-len(panels) // columns)
    figure, axes = plt.subplots(rows, columns, figsize=(7 * columns, 4.2 * rows), squeeze=False)
    for ax, (name, distribution) in zip(axes.flat, panels, strict=False):
        for label, histogram in distribution["series"].items():
            total = sum(c for _, c in histogram)
            xs, tail, seen = [], [], 0
            for edge, count in histogram:
                seen += count
                if seen < total:
                    xs.append(edge)
                    tail.append((total - seen) / total)
            ax.step(xs, tail, where="post", label=f"{label} (n={total})")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("µs")
        ax.set_ylabel("share of samples above")
        ax.set_title(f"{name}: {distribution['title']}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    figure.suptitle("akd_ros bench/run.py: distributions (tails: 1 - CDF); a shared, noisy machine")
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip", action="append", default=[], help=f"sections to leave out, of {', '.join(SECTIONS)}")
    parser.add_argument("--render", action="store_true", help="only render RESULTS.md and results.png again")
    parser.add_argument(
        "--again", action="append", default=[], help="sections to run again, keeping the last run's others"
    )
    args = parser.parse_args()
    skipped = {s for value in args.skip for s in value.split(",") if s}
    again = [s for value in args.again for s in value.split(",") if s]
    for option, names in (("--skip", skipped), ("--again", set(again))):
        if unknown := names - set(SECTIONS):
            parser.error(f"{option}: no section {', '.join(sorted(unknown))}; the sections: {', '.join(SECTIONS)}")
    RESULTS.mkdir(exist_ok=True)
    summary_path = RESULTS / "run.json"
    if (args.render or again) and not summary_path.exists():
        print(f"run.py: nothing to keep: {summary_path.relative_to(ROOT)} missing (run the suite first)")
        return 1
    if args.render or again:
        summary = json.loads(summary_path.read_text())
        records = summary.pop("records")
        if again:
            date = utc_now()
            for name in again:
                records[name] = run_section(name)
            command = shlex.join([".venv/bin/python", "bench/run.py", *(f"--again={s}" for s in again)])
            summary["again"] = {"date": date, "command": command, "sections": again}
            summary_path.write_text(json.dumps(summary | {"records": records}, indent=1))
    else:
        started, at_start = time.monotonic(), machine()
        date = utc_now()
        records = {}
        for name in SECTIONS:
            records[name] = {"status": "skipped"} if name in skipped else run_section(name)
            records[name].setdefault("command", shlex.join(["bench/" + SECTIONS[name][0][0], *SECTIONS[name][0][1:]]))
        command = shlex.join([".venv/bin/python", "bench/run.py", *(f"--skip={s}" for s in sorted(skipped))])
        summary = {
            "command": command,
            "date": date,
            "seconds": time.monotonic() - started,
            "machine": at_start,
            "machine_at_end": machine(),
        }
        summary_path.write_text(json.dumps(summary | {"records": records}, indent=1))
    (BENCH / "RESULTS.md").write_text(render(records, summary))
    plot(records, BENCH / "results.png")
    bad = [n for n, r in records.items() if r["status"] not in ("measured", "skipped")]
    print(f"run.py: RESULTS.md and results.png written; {len(records) - len(bad)} of {len(records)} sections fine")
    for name in bad:
        record = records[name]
        print(f"run.py: {name}: {record['status']}: {record.get('why') or '; '.join(record.get('not_measured', []))}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
