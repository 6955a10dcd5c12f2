"""akd-scan LINK: lists the slaves on a bus, one line each.

Each line gives position, vendor id, product code, revision, name and AL state, then the AKD's
model and firmware strings and, when the slave reports one, the AL status code with its name.
State and code are those the scan found; the scan leaves every slave in Init.
"""

from __future__ import annotations

import argparse
import sys

from akd_ros.cli.common import EXIT_FAILURE, add_master_arguments, open_master, run

EXAMPLES = """examples:
  akd-scan sim:2                      two virtual AKDs in this process
  akd-scan udp://127.0.0.1:34980      the virtual AKDs of akd-sim --udp 127.0.0.1:34980
  akd-scan enp3s0 --pcap scan.pcapng  the drives on an interface, every frame written for Wireshark
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


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-scan."""
    parser = argparse.ArgumentParser(
        prog="akd-scan",
        description=__doc__.splitlines()[0],
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_master_arguments(parser)
    args = parser.parse_args(argv)

    def body() -> int:
        master = open_master(args)
        try:
            slaves = master.scan()
        finally:
            master.close()
        if not slaves:
            print(f"akd-scan: no slave answered on {args.link}", file=sys.stderr)
            return EXIT_FAILURE
        for slave in slaves:
            print(format_slave(slave))
        return 0

    return run("akd-scan", body)


if __name__ == "__main__":
    sys.exit(main())
