"""Shared fixtures of the Python suite.

The suite runs against the extension built by `pip install -e .` (scripts/setup.sh). Real-drive
and real-terminal data is read from `<repo>/../shared/real-akd/` and `real-ethercat/` and never
copied into the project; tests that need it skip with the reason where it is absent (a user's
clone).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from support import recovery_table
from support.netns import free_udp_port, veth_pair

REPO = Path(__file__).resolve().parents[1]
REAL_AKD = REPO.parent / "shared" / "real-akd"
REAL_ETHERCAT = REPO.parent / "shared" / "real-ethercat"


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The repository's root directory."""
    return REPO


@pytest.fixture(scope="session")
def real_akd_dir() -> Path:
    """`../shared/real-akd/` (SII image and capture of a real AKD); skips where it is absent."""
    if not REAL_AKD.is_dir():
        pytest.skip(f"real-drive data not present at {REAL_AKD} (only in the project's CI)")
    return REAL_AKD


@pytest.fixture(scope="session")
def real_ethercat_dir() -> Path:
    """`../shared/real-ethercat/` (SII images and captures of real Beckhoff terminals); skips where it is absent."""
    if not REAL_ETHERCAT.is_dir():
        pytest.skip(f"real-terminal data not present at {REAL_ETHERCAT} (only in the project's CI)")
    return REAL_ETHERCAT


@pytest.fixture
def udp_port() -> int:
    """A UDP port on 127.0.0.1 that was free when the test started."""
    return free_udp_port()


@pytest.fixture
def veth():
    """Two fresh network namespaces joined by a veth pair (see support.netns.VethPair);
    removed after the test; skips where namespaces are not permitted."""
    with veth_pair() as net:
        yield net


def pytest_terminal_summary(terminalreporter) -> None:
    """Prints the recovery table's rows measured in this run (tests/test_recovery.py), as docs/howto/recovery.md quotes
    them."""
    if recovery_table.ROWS:
        terminalreporter.write_sep("-", "recovery table (measured in this run)")
        for line in recovery_table.lines():
            terminalreporter.write_line(line)
