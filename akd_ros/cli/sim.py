"""akd-sim: serves virtual AKDs, or a line of AKDs and terminals, on a UDP port or a network interface until
SIGINT/SIGTERM.

With --udp the EtherCAT payload travels as the UDP payload (the master's 'udp://HOST:PORT'
link); with --iface the virtual slaves answer raw EtherCAT frames on that interface as a real
line would (for a veth end, or a spare port wired to a master). --count N serves N AKDs; --line
names the slaves in order, e.g. 'ek1100,el1004,el2004,akd' (an EK1100 coupler, EL1004 and EL1008
digital inputs, EL2004 and EL2008 digital outputs, an EL3102 with two analog inputs, AKDs).

While it serves, akd-sim takes commands on stdin, one a line, each answered with one line on
stdout, 'ok ...' or 'error: ...'. POSITION is a slave's place on the line, from 0; INPUT counts
from 1:

  fault POSITION NAME                 raise a fault in an AKD, e.g. 'fault 0 F439', 'fault 0 sync_lost'
  hardware_enable POSITION high|low   set an AKD's hardware enable input
  toggles POSITION INPUT P1,P2,...    an AKD's digital input 1..7 toggles at these positions
                                      (counts); without positions it stays low
  input POSITION INPUT high|low       a digital input high or low: an AKD's 1..7 wherever the
                                      axis is, an EL1004's 1..4 or EL1008's 1..8 at its connector
                                      (the master sees it after the terminal's 3 ms filter)
  switch POSITION NAME on|off         a switch of an AKD's 0x60FD active or not: negative_limit,
                                      positive_limit (each stops motion toward it), home_switch,
                                      interlock
  analog_input POSITION [INPUT] VOLTS an analog input, within ±10 V: an AKD's one, an EL3102's
                                      1 or 2 (INPUT 1 where it is left out)
  state POSITION                      an AKD's firmware state as JSON, with "dc": what its
                                      synchronisation was told (SYNC0, FBUS.PARAM02, 0x60C2), and
                                      its I/O: digital_inputs (0x60FD), digital_outputs and
                                      analog_output (V) as the master drives them; a terminal's
                                      AL state and I/O: inputs (as the master reads them),
                                      outputs (as its pins drive them: off outside Op and once
                                      the sync-manager watchdog ran out), analog_inputs (V)
  power_cycle POSITION                the slave loses power and comes back as at power-up (AL
                                      Init, station address 0; an AKD Not ready to switch on,
                                      not homed)
  homing POSITION ok|error|no_reference
                                      an AKD's homing works, stops halfway with a homing
                                      error, or never finds its reference (searches on)
  cable POSITION pulled|plugged       pull the cable in front of the slave out (frames reach
                                      only the slaves before it), or plug it back in
  link POSITION PORT down|up          take the link at a port of the slave down or up again: the
                                      cable there pulled or plugged (port 0: the cable in front
                                      of it, 'link 3 0 down' is 'cable 3 pulled'; port 1: the
                                      cable to the next slave), both ends counting a lost link
  crc POSITION PORT COUNT [EVERY]     a faulty cable into a port of the slave spoils the CRC of
                                      the next COUNT frames entering there, one in every EVERY
                                      (1 where left out): the slave counts an invalid frame at
                                      that port, every slave after it on the frame's way a
                                      forwarded error, and the master never gets the frame.
                                      Frames enter port 0 on their way out, from the slave in
                                      front ('crc 3 0 200': the cable from slave 2 into slave 3),
                                      and port 1 on their way back, from the slave behind
                                      ('crc 3 1 200': the cable from slave 4 into slave 3)
  counters POSITION                   the slave's ESC as JSON: its DL status, each of its ports
                                      with its link, the frames a fault is still to spoil there
                                      and its error counters as the master reads them
                                      ("registers": they stop at 255 and a master clears them)
                                      and as counted since power-up ("counted")
  drop FRAMES                         the next FRAMES frames get no reply at all
  corrupt FRAMES                      the next FRAMES replies come back corrupted
  wrong_wkc FRAMES                    the next FRAMES replies carry a wrong working counter
                                      (FRAMES 0 ends a burst still pending)
  help                                the commands

A change reaches the drive at once; the drive firmware acts on it when it next runs, at the
next frame a master sends. The end of stdin ends the commands, not the simulator.

At SIGINT or SIGTERM akd-sim says what it served, and on an interface how late its replies went
back because it was not run: from the frame's arrival, as the kernel stamped it, to akd-sim taking
it up, less its own work meanwhile. A master counts a reply later than its time-out as a lost
frame, which a real ESC, answering in hardware, never causes:

  akd-sim: served 1062 frames (0 malformed, 0 lost on the line, 0 unsent); replies late because
  akd-sim was not run: 2 over 0.25 ms, 0 over 0.5 ms, 0 over 1 ms, 0 over 2 ms, 0 over 4 ms,
  longest 0.31 ms; its own serving of a frame took 0 over 0.25 ms, 0 over 0.5 ms, 0 over 1 ms,
  0 over 2 ms, 0 over 4 ms, slowest 0.02 ms

Its own serving (the drives answering a frame, some 50 µs for 64 drives, more on a busy host)
adds to the round trip too, and is not counted as late.

--setpoint-trace FILE writes, for each drive in Op, every change of the set-points its RxPDO
carries (target position 0x607A, target velocity 0x60FF, target torque 0x6071, controlword
0x6040, modes of operation 0x6060, those mapped) as JSON lines, stamped when the frame carrying
it was received:

  {"drive":0,"frame":5231,"index":143,"realtime_ns":...,"monotonic_ns":...,"position":1234.5,
   "changed":["target_position"],"target_position":1669,"controlword":15,"modes_of_operation":8}

frame: the line's count of frames; index: the master's index in the frame's first datagram;
realtime_ns, monotonic_ns: CLOCK_REALTIME and CLOCK_MONOTONIC at reception; position: the actual
position 0x6064 (counts); changed: the values that changed. A thread of its own writes the file;
changes it could not take in time are dropped and counted. The last line, written at SIGINT or
SIGTERM, is {"end":{"changes":N,"dropped":M}}, also said on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading

from akd_ros import _native
from akd_ros.cli.common import run, signals_held, tool_parser

USAGE = {
    "fault": "fault POSITION NAME",
    "hardware_enable": "hardware_enable POSITION high|low",
    "toggles": "toggles POSITION INPUT P1,P2,...",
    "input": "input POSITION INPUT high|low",
    "switch": "switch POSITION NAME on|off",
    "analog_input": "analog_input POSITION [INPUT] VOLTS",
    "state": "state POSITION",
    "power_cycle": "power_cycle POSITION",
    "homing": "homing POSITION ok|error|no_reference",
    "cable": "cable POSITION pulled|plugged",
    "link": "link POSITION PORT down|up",
    "crc": "crc POSITION PORT COUNT [EVERY]",
    "counters": "counters POSITION",
    "drop": "drop FRAMES",
    "corrupt": "corrupt FRAMES",
    "wrong_wkc": "wrong_wkc FRAMES",
    "help": "help",
}

# The commands that take a count of frames, and the Simulator method each calls.
BURSTS = {"drop": "drop_frames", "corrupt": "corrupt_frames", "wrong_wkc": "wrong_wkc"}


class CommandError(ValueError):
    """A command line that is not one of the commands; the message names what is allowed."""


def parse_host_port(text: str) -> tuple[str, int]:
    """Splits 'HOST:PORT' ('[::1]:PORT' for IPv6); raises ValueError naming the problem."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"--udp expects HOST:PORT with a port in 1..65535, got {text!r}")
    return host.strip("[]"), int(port)


def count_argument(text: str) -> int:
    """The --count value: at least one virtual AKD."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expects a whole number of drives >= 1, got {text!r}")
    return int(text)


def _whole_number(text: str, what: str, allowed: str) -> int:
    # The bound keeps a number too long for the native side an error that names the range.
    if not text.isdigit() or int(text) >= 2**32:
        raise CommandError(f"{what} must be a whole number {allowed}, got {text!r}")
    return int(text)


def _toggle_positions(text: str) -> list[float]:
    """The positions of 'P1,P2,...'; the simulator refuses those that are not finite."""
    try:
        return [float(p) for p in text.split(",")]
    except ValueError:
        raise CommandError(
            f"toggle positions are counts separated by commas, e.g. 1000,-2500.5; got {text!r}"
        ) from None


def execute(simulator, line: str) -> str | None:
    """Carries out one command line on `simulator` (an akd_ros.Simulator) and gives its answer,
    'ok ...' (None for a blank line); raises CommandError or the simulator's EtherCatError."""
    words = line.split()
    if not words:
        return None
    name, args = words[0], words[1:]
    if name not in USAGE:
        raise CommandError(f"unknown command {name!r}: allowed are {', '.join(USAGE)}")
    if name == "help":
        return "ok commands: " + " | ".join(USAGE.values())
    arity = {
        "fault": (2,),
        "hardware_enable": (2,),
        "toggles": (2, 3),
        "input": (3,),
        "switch": (3,),
        "analog_input": (2, 3),
        "cable": (2,),
        "homing": (2,),
        "link": (3,),
        "crc": (3, 4),
    }.get(name, (1,))
    if len(args) not in arity:
        raise CommandError(f"usage: {USAGE[name]}")
    if name in BURSTS:
        getattr(simulator, BURSTS[name])(_whole_number(args[0], "FRAMES", "0 or more"))
        return "ok " + " ".join(words)
    position = _whole_number(args[0], "POSITION", f"0..{len(simulator) - 1}")
    # What a position names is the simulator's to say; past the line, it names the line's length.
    product = simulator.products[position] if position < len(simulator) else None
    if name == "fault":
        simulator.inject_fault(position, args[1])
    elif name == "hardware_enable":
        levels = {"high": True, "low": False}
        if args[1] not in levels:
            raise CommandError(f"hardware_enable takes high or low, got {args[1]!r}")
        simulator.set_hardware_enable(position, levels[args[1]])
    elif name == "toggles":
        digital_input = _whole_number(args[1], "INPUT", "from 1")
        positions = _toggle_positions(args[2]) if len(args) == 3 else []
        simulator.set_input_toggles(position, digital_input, positions)
    elif name == "input":
        levels = {"high": True, "low": False}
        if args[2] not in levels:
            raise CommandError(f"input takes high or low, got {args[2]!r}")
        simulator.set_input(position, _whole_number(args[1], "INPUT", "from 1"), levels[args[2]])
    elif name == "switch":
        if args[2] not in ("on", "off"):
            raise CommandError(f"switch takes on or off, got {args[2]!r}")
        simulator.set_switch(position, args[1], args[2] == "on")
    elif name == "analog_input":
        analog_input = _whole_number(args[1], "INPUT", "from 1") if len(args) == 3 else 1
        try:
            volts = float(args[-1])
        except ValueError:
            raise CommandError(f"analog_input takes a voltage such as 2.5, got {args[-1]!r}") from None
        simulator.set_analog_input(position, volts, analog_input)
    elif name == "power_cycle":
        simulator.power_cycle(position)
    elif name == "homing":
        simulator.set_homing_failure(position, args[1])
    elif name == "cable":
        if args[1] not in ("pulled", "plugged"):
            raise CommandError(f"cable takes pulled or plugged, got {args[1]!r}")
        (simulator.pull_cable if args[1] == "pulled" else simulator.replug_cable)(position)
    elif name == "link":
        if args[2] not in ("down", "up"):
            raise CommandError(f"link takes down or up, got {args[2]!r}")
        simulator.set_link(position, _whole_number(args[1], "PORT", "0..3"), args[2] == "up")
    elif name == "crc":
        port = _whole_number(args[1], "PORT", "0..3")
        count = _whole_number(args[2], "COUNT", "0 or more (0 ends a fault still pending)")
        every = _whole_number(args[3], "EVERY", "1 or more") if len(args) == 4 else 1
        simulator.crc_errors(position, port, count, every)
    elif name == "counters":
        return "ok " + json.dumps(simulator.esc_state(position))
    elif product in (None, "akd"):
        # The state as CiA 402 writes it ("Operation enabled"), as the line has always said it.
        return "ok " + json.dumps(simulator.drive_state(position), default=str)
    else:
        return "ok " + json.dumps(simulator.terminal_state(position))
    return "ok " + " ".join(words)


def answer(simulator, line: str) -> str | None:
    """The reply line to one command line: 'ok ...' or 'error: ...' (None for a blank line)."""
    from akd_ros import EtherCatError

    try:
        return execute(simulator, line)
    except (CommandError, EtherCatError) as error:
        return f"error: {error}"


def serve_commands(simulator, fd: int = 0) -> None:
    """Answers the command lines read from `fd` until its end. Reads the descriptor itself, not
    sys.stdin: this thread may still wait in a read when the interpreter shuts down, and must
    then hold none of sys.stdin's locks."""
    pending = b""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:
            return
        if not chunk:
            return
        *lines, pending = (pending + chunk).split(b"\n")
        for line in lines:
            reply = answer(simulator, line.decode("utf-8", errors="replace"))
            if reply is not None:
                # One write per reply, so that a reply stays one line next to the main thread's.
                sys.stdout.write(reply + "\n")
                sys.stdout.flush()


def served_line(stats: dict) -> str:
    """The line akd-sim says at its stop: what it served, on an interface how late its replies went back because it
    was not run, and how long its own serving of a frame took (a master counts a reply later than its time-out as a
    lost frame, whichever made it late)."""
    line = (
        f"akd-sim: served {stats['served']} frames ({stats['malformed']} malformed, {stats['lost']} lost on the line,"
        f" {stats['unsent']} unsent)"
    )
    if stats["would_be_f125"]:
        line += f"; {stats['would_be_f125']} times a real AKD would have raised F125 (--missed warn)"
    late = stats["late"]
    if late is not None:
        over = ", ".join(f"{count} over {bound / 1000:g} ms" for bound, count in late["over"].items())
        longest = late["longest_us"] / 1000
        line += f"; replies late because akd-sim was not run: {over}, longest {longest:.2f} ms"
    serving = stats["serving"]
    over = ", ".join(f"{count} over {bound / 1000:g} ms" for bound, count in serving["over"].items())
    line += f"; its own serving of a frame took {over}, slowest {serving['longest_us'] / 1000:.2f} ms"
    return line


def start_commands(simulator, fd: int = 0) -> None:
    """Answers the commands read from `fd` (stdin) on a thread of their own while the simulator serves; a stop asked
    meanwhile waits until the thread has started (`signals_held`)."""
    with signals_held():
        threading.Thread(target=serve_commands, args=(simulator, fd), name="akd-sim commands", daemon=True).start()


EXAMPLES = """
examples:
  akd-sim --udp 127.0.0.1:34980 --count 2                two virtual AKDs for the link udp://127.0.0.1:34980
  akd-sim --iface veth-sim --count 6                     six on a veth end, for a master on its peer
  akd-sim --iface veth-sim --line ek1100,el1004,el2004,akd  a coupler, 4 inputs, 4 outputs and an AKD
"""


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-sim."""
    parser = tool_parser("akd-sim", __doc__.splitlines()[0], __doc__.split("\n\n", 2)[2] + EXAMPLES)
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--udp", metavar="HOST:PORT", help="serve EtherCAT over UDP here")
    where.add_argument("--iface", metavar="NAME", help="serve raw EtherCAT on this interface")
    slaves = parser.add_mutually_exclusive_group()
    slaves.add_argument(
        "--count", type=count_argument, default=1, metavar="N", help="number of virtual AKDs in the line (default 1)"
    )
    slaves.add_argument(
        "--line",
        metavar="SPEC",
        help=f"the slaves in order, separated by commas, each one of {', '.join(_native.SIM_PRODUCTS)} "
        "(e.g. ek1100,el1004,el2004,akd)",
    )
    parser.add_argument(
        "--missed",
        choices=_native.MISSED_FRAMES,
        default="late",
        help="how the drives judge missed frames (F125 after more than 7): 'late' (default), as the real drive, "
        "by time; 'warn', by time too, but where a real AKD would raise F125 the drive says so on stderr and goes on "
        "(for a host whose master thread is not real-time); 'lost', only frames lost on the line",
    )
    parser.add_argument(
        "--pace",
        choices=_native.PACES,
        default="real",
        help="how fast the drives' firmware answers: 'real' (default), as the real drive (Init->PreOp 17.5 ms the "
        "first time after power-up and 4.5 ms later, other AL requests 4.5 ms, the first mailbox reply 30 ms and "
        "later ones 1 ms); 'immediate', before the next frame",
    )
    parser.add_argument(
        "--setpoint-trace",
        metavar="FILE",
        help="write every change of the set-points the drives receive to FILE (JSON lines, see below)",
    )
    parser.add_argument(
        "--busy-poll",
        action="store_true",
        help="with --iface: never sleep between frames, answering each as it arrives as the drive's ESC does, "
        "so a master's round trip holds no wake-up of this process (a CPU of its own; the normal scheduler)",
    )
    args = parser.parse_args(argv)
    if args.busy_poll and not args.iface:
        parser.error("--busy-poll needs --iface: over UDP the host's IP stack answers in its own time")

    def body() -> int:
        from akd_ros import SetpointTrace, serve_iface, serve_udp

        drives = f"line {args.line}" if args.line else f"{args.count} virtual AKD{'s' if args.count > 1 else ''}"
        trace = SetpointTrace(args.setpoint_trace) if args.setpoint_trace else None
        where = f"udp {args.udp}" if args.udp else f"interface {args.iface}"

        def on_start(simulator) -> None:
            # Said once the socket is bound and the line made, so that a client that waits for this line finds the
            # simulator there; a socket or a line that cannot be made is said instead.
            print(f"akd-sim: starting {drives} on {where}", flush=True)
            start_commands(simulator)

        options = {
            "on_start": on_start,
            "missed": args.missed,
            "pace": args.pace,
            "setpoint_trace": trace,
            "on_stop": lambda stats: print(served_line(stats), flush=True),
            "line": args.line,
        }
        try:
            if args.udp:
                host, port = parse_host_port(args.udp)
                serve_udp(host, port, args.count, **options)
            else:
                serve_iface(args.iface, args.count, busy_poll=args.busy_poll, **options)
        except KeyboardInterrupt:
            # SIGINT and SIGTERM are how a simulator is meant to stop; a second signal while
            # it stops must not turn the clean stop into an interrupted one.
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        finally:
            if trace is not None:
                summary = trace.close()
                print(
                    f"akd-sim: set-point trace {args.setpoint_trace}: {summary['changes']} changes,"
                    f" {summary['dropped']} dropped",
                    flush=True,
                )
        print("akd-sim: stopped", flush=True)
        return 0

    return run("akd-sim", body)


if __name__ == "__main__":
    sys.exit(main())
