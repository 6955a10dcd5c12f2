"""The pcapng reader the tests use (tests/support/pcapng_reader.py): any bytes as a capture
file. Reading either yields packets that lie within the file, each with the bytes its block
says it captured, or stops with a PcapngError that names the problem; nothing else escapes.

Run with atheris (coverage-guided, libFuzzer's engine and flags): see run.sh.
"""

import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tests"))
with atheris.instrument_imports():
    from support.pcapng_reader import PcapngError, parse_packets


def test_one_input(data: bytes) -> None:
    last = 0
    try:
        for packet in parse_packets(data):
            assert packet.number == last + 1, (packet.number, last)
            assert len(packet.data) <= len(data)
            last = packet.number
    except PcapngError:
        pass


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
