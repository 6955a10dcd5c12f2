"""akd-scan LINK: lists the slaves on a bus, one line each.

Each line gives position, vendor id, product code, revision, name and AL state, then the AKD's
model and firmware strings and, when the slave reports one, the AL status code with its name.
State and code are those the scan found; the scan leaves every slave in Init.

With --line it then reads the line at rest: a line saying where errors first appear (the cable's
words, as akd_node's /diagnostics says them), and one line per port of each slave with its link,
what is at its other end and what its ESC counted since power-up or the last clear (nothing is
cleared).
"""

from __future__ import annotations

import argparse
import sys

from akd_ros.cli.common import EXIT_FAILURE, add_master_arguments, open_master, run

EXAMPLES = """examples:
  akd-scan sim:2                      two virtual AKDs in this process
  akd-scan udp://127.0.0.1:34980      the virtual AKDs of akd-sim --udp 127.0.0.1:34980
  akd-scan enp3s0 --pcap scan.pcapng  the drives on an interface, every frame written for Wireshark
  akd-scan sim:6 --line               six virtual AKDs, then their ports, links and error counters
"""


def format_slave(slave: dict) -> str:
    """One line describing a slave as `Master.scan()` reports it."""
    line = (
        f"{slave['position']} vendor=0x{slave['vendor_id']:08X} "
        f"product=0x{slave['product_code']:08X} revision=0x{slave['revision']:08X} "
        f"name={slave['name']!r} state={slave['found_al_state']}"
    )
    if slave.get("model"):
        line += f" model={slave['model']}"
    if slave.get("firmware"):
        line += f" firmware={slave['firmware']}"
    if slave["found_al_status_code"]:
        line += f" al_status_code=0x{slave['found_al_status_code']:04X} ({slave['found_al_status_code_name']})"
    return line


def format_line(line: dict) -> list[str]:
    """The lines saying what `Master.line_health()` found: where errors first appear, then each port of each slave."""
    lines = [f"line: {line['summary']}"]
    for slave in line["slaves"]:
        name = f"slave {slave['position']} ({slave['name']})"
        if not slave["answered"]:
            lines.append(f"{name}: no answer")
            continue
        for port in slave["ports"]:
            to = "" if port["peer"] == "nothing" else f", to {port['peer']}"
            lines.append(f"{name} port {port['port']} ({port['kind']}): {port['link']}{to}; {port['counted']}")
        total = slave["total"]
        if total["processing_unit_errors"] or total["pdi_errors"]:
            lines.append(
                f"{name}: {total['processing_unit_errors']} processing unit errors, {total['pdi_errors']} PDI errors"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-scan."""
    parser = argparse.ArgumentParser(
        prog="akd-scan",
        description=__doc__.splitlines()[0],
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_master_arguments(parser)
    parser.add_argument(
        "--line",
        action="store_true",
        help="then each slave's ports: their links, what is at their other ends, the error counters since power-up",
    )
    args = parser.parse_args(argv)

    def body() -> int:
        master = open_master(args)
        try:
            slaves = master.scan()
            line = master.line_health() if slaves and args.line else None
        finally:
            master.close()
        if not slaves:
            print(f"akd-scan: no slave answered on {args.link}", file=sys.stderr)
            return EXIT_FAILURE
        for slave in slaves:
            print(format_slave(slave))
        for text in format_line(line) if line else ():
            print(text)
        return 0

    return run("akd-scan", body)


if __name__ == "__main__":
    sys.exit(main())
