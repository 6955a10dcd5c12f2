"""akd-scan LINK: lists the slaves on a bus, one line each.

Each line gives position, vendor id, product code, revision, name and AL state, then the AKD's
model and firmware strings and, when the slave reports one, the AL status code with its name.
State and code are those the scan found; the scan leaves every slave in Init. With --pdos, each
slave's channels follow its line: the PDO entries its SII gives its sync managers, named as the
node names them. With --params FILE, akd-scan also writes a parameters file for akd_node of the line
it found (each AKD a joint, every other slave a device), which the node takes as it is.

With --line it then reads the line at rest: a line saying where errors first appear (the cable's
words, as akd_node's /diagnostics says them), and one line per port of each slave with its link,
what is at its other end and what its ESC counted since power-up or the last clear (nothing is
cleared).
"""

from __future__ import annotations

import sys

from akd_ros.cli.common import EXIT_FAILURE, add_master_arguments, open_master, run, tool_parser

EXAMPLES = """examples:
  akd-scan sim:2                      two virtual AKDs in this process
  akd-scan udp://127.0.0.1:34980      the virtual AKDs of akd-sim --udp 127.0.0.1:34980
  akd-scan enp3s0 --pcap scan.pcapng  the drives on an interface, every frame written for Wireshark
  akd-scan sim:ek1100,el2004,akd --pdos --params cell.yaml  a cell's channels, akd_node's parameters for it
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


def format_channels(slave: dict) -> list[str]:
    """The lines of a slave's channels under its line: each its direction, name, object, data type, bits and PDO; an
    AKD's are those of its SII's own assignment, which the node replaces with the joint's mapping."""
    if not slave["channels"]:
        return ["  no process data"]
    lines = ["  as its SII assigns them (the node maps a joint's drive as its mapping says):"] if slave["akd"] else []
    for c in slave["channels"]:
        lines.append(
            f"  {c['direction']:6} {c['name']} 0x{c['index']:04X}:{c['subindex']:02X} {c['data_type']} "
            f"{c['bits']} bit{'s' if c['bits'] > 1 else ''} (PDO 0x{c['pdo']:04X})"
        )
    return lines


def parameters_file(link: str, slaves: list[dict]) -> str:
    """akd_node's parameters for the line `slaves` on `link`: each AKD a joint (joint_1, joint_2, ... in line order)
    at its position, every other slave a device named after its order number and position (el2004_2) at its
    position, with its product; the node checks the line against it before anything goes to Op."""
    from akd_ros.device import device_name

    joints = [(f"joint_{n}", s) for n, s in enumerate((s for s in slaves if s["akd"]), 1)]
    devices = [(device_name(s), s) for s in slaves if not s["akd"]]
    lines = [
        f"# akd_node's parameters for the line akd-scan found on {link}:",
        "# each AKD a joint, every other slave a device, at its position, checked against the line before anything",
        "# goes to Op. Give each joint its mode, mapping and mechanics (counts_per_revolution, gear_ratio, limits.*:",
        "# docs/reference/parameters.md) before it moves.",
        "akd_node:",
        "  ros__parameters:",
        f"    link: {_yaml(link)}",
    ]
    if joints:
        lines.append(f"    joints: [{', '.join(name for name, _ in joints)}]")
        for name, s in joints:
            lines.append(f"    joints.{name}.slave: {s['position']}  # {s.get('model') or s['name']}")
    if devices:
        lines.append(f"    devices: [{', '.join(name for name, _ in devices)}]")
        for name, s in devices:
            channels = ", ".join(c["name"] for c in s["channels"]) or "no process data"
            lines.append(f"    devices.{name}.slave: {s['position']}  # {s['name']}: {channels}")
            if s.get("order"):
                lines.append(f"    devices.{name}.product: {_yaml(s['order'])}")
    return "\n".join(lines) + "\n"


def _yaml(text: str) -> str:
    """`text` as a YAML scalar that reads back as that string."""
    import yaml

    return yaml.safe_dump(text, default_style=None, width=1000).strip().removesuffix("\n...").strip()


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
    parser = tool_parser("akd-scan", __doc__.splitlines()[0], EXAMPLES)
    add_master_arguments(parser)
    parser.add_argument("--pdos", action="store_true", help="under each slave, the channels its process data carries")
    parser.add_argument(
        "--params",
        metavar="FILE",
        help="write akd_node's parameters for the line found to FILE (each AKD a joint, every other slave a device)",
    )
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
            if args.pdos:
                print("\n".join(format_channels(slave)))
        if args.params:
            with open(args.params, "w", encoding="utf-8") as out:
                out.write(parameters_file(args.link, slaves))
            print(f"akd-scan: wrote {args.params}: akd_node --ros-args --params-file {args.params}", file=sys.stderr)
        for text in format_line(line) if line else ():
            print(text)
        return 0

    return run("akd-scan", body)


if __name__ == "__main__":
    sys.exit(main())
