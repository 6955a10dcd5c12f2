"""scripts/module_deps.py sees what it checks: a cycle, a dependency up a layer, the EtherCAT layer reaching for the
drive profile and the EtherCAT layer naming a device's object planted in a scratch tree fail it, wherever in the code
they are written, and text that only looks like code (strings, comments, doc comments, tests) does not."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "scripts" / "module_deps.py"

# A string continued over a line with `\`, a `"` right after a word (`header"`), raw strings with and without #,
# char literals of a quote, lifetimes and doc comments: each threw the old text-stripping check off its pairing of
# quotes (a path after them was lost, or text inside them taken for code).
TRICKY = r"""
//! Module docs may name crate::ethercat::master::Master: docs link anywhere.
/// So may an item's: [`crate::ethercat::master::Master`].
pub const CONTINUED: &str = "a string continued \
    over a line, with a quote after a word: header\" and crate::ethercat::master::Master inside";
pub const RAW: &str = r#"a raw string with "quotes" and crate::ethercat::master::Master"#;
pub const QUOTE: char = '"';
pub fn lifetime<'a>(s: &'a str) -> &'a str { s }
/* a block comment naming crate::ethercat::master::Master and 0x6060 */
/// A doc comment naming the AKD's 0x60C2.
pub const NOT_CODE: &str = "0x6060 in a string";
pub const MASKS: [u16; 3] = [0x8000, 0x88A4, 0x1C12];
"""


def _tree(root: Path, rust: dict[str, str], python: dict[str, str]) -> Path:
    for name, text in rust.items():
        path = root / "native" / "src" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for name, text in python.items():
        path = root / "akd_ros" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def _check(root: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), "--root", str(root)], capture_output=True, text=True, timeout=600
    )


# The crate's shape: products in folders, the umbrella error beside them over both the EtherCAT layer's codecs and the
# drive profile's (a cycle of folders, not of the layers' units), the drive profile on the master, the virtual AKD on
# the codecs, links and the profile's codecs.
CLEAN_RUST = {
    "lib.rs": "pub mod error;\npub mod ethercat;\npub mod drive;\npub mod sim;\n",
    "ethercat/mod.rs": "pub mod frame;\npub mod sii;\npub mod link;\npub mod master;\n",
    "ethercat/frame.rs": TRICKY
    + "pub struct Frame;\n#[cfg(test)]\nmod tests {\n    use crate::ethercat::master::Master;\n"
    + "    const M: u16 = 0x6060;\n}\n",
    "ethercat/sii.rs": "use crate::ethercat::frame::Frame;\npub struct Identity(pub Frame);\n",
    "error.rs": "pub enum Error { Sii(crate::ethercat::sii::Identity), Pdo(crate::drive::pdo::PdoError) }\n",
    "ethercat/link/mod.rs": "pub mod udp;\nuse crate::error::Error;\npub fn f(_: Error) {}\n",
    "ethercat/link/udp.rs": "use super::f;\npub fn g() { let _ = f; }\n",
    "ethercat/master/mod.rs": "use crate::ethercat::{link::udp::g, frame::{self, Frame}};\npub struct Master(Frame);\n",
    "drive/mod.rs": "pub mod pdo;\npub mod akd;\n",
    "drive/pdo.rs": "use crate::ethercat::frame::Frame;\npub struct PdoError(pub Frame);\n",
    "drive/akd.rs": "use crate::ethercat::master::Master;\npub fn configure(_: &mut Master) {}\n",
    "sim/mod.rs": "pub fn serve() { crate::ethercat::link::udp::g(); let _ = crate::drive::pdo::PdoError; }\n",
}
CLEAN_PYTHON = {
    "__init__.py": "",
    "units.py": "import math\n",
    "bus.py": "from akd_ros import _native, units\n",
    "node/__init__.py": "from akd_ros.bus import units\nfrom . import core\n",
    "node/core.py": "from ..bus import units\n",
}


def test_a_clean_tree_passes(tmp_path):
    checked = _check(_tree(tmp_path, CLEAN_RUST, CLEAN_PYTHON))
    assert checked.returncode == 0, checked.stderr
    assert "no cycles, no dependency up a layer" in checked.stdout


@pytest.mark.parametrize(
    ("planted", "expected"),
    [
        # A cycle between two codecs, the path written after the continued string and the raw strings.
        (
            {"ethercat/frame.rs": TRICKY + "use crate::ethercat::sii::Identity;\npub struct Frame;\n"},
            "rust: cycle among the modules of the crate: ethercat::frame <-> ethercat::sii",
        ),
        # A codec naming the master, up two layers, in a function body and in a macro's tokens.
        (
            {
                "ethercat/frame.rs": TRICKY
                + "pub struct Frame;\npub fn f() { let _ = crate::ethercat::master::Master; }\n"
            },
            "rust: ethercat::frame depends on ethercat::master, a layer above it",
        ),
        (
            {
                "ethercat/frame.rs": TRICKY
                + 'pub struct Frame;\npub fn f() { println!("{:?}", crate::ethercat::link::f); }\n'
            },
            "rust: ethercat::frame depends on ethercat::link, a layer above it",
        ),
        # The EtherCAT layer reaching for the drive profile: a codec for one of the same layer, the master for one below
        # it, which no layer rule forbids.
        (
            {"ethercat/sii.rs": "use crate::drive::pdo::PdoError;\npub struct Identity(pub PdoError);\n"},
            "rust: ethercat::sii depends on drive::pdo, a module kept apart from it",
        ),
        (
            {"ethercat/master/mod.rs": "pub struct Master(crate::drive::pdo::PdoError);\n"},
            "rust: ethercat::master depends on drive::pdo, a module kept apart from it",
        ),
        # The virtual AKD reaching into the master, one layer but kept apart, or through the drive profile's use of it.
        (
            {"sim/mod.rs": "use crate::ethercat::master::Master;\n"},
            "rust: sim depends on ethercat::master, a module kept apart from it",
        ),
        ({"sim/mod.rs": "use crate::drive::akd::configure;\n"}, "rust: sim depends on drive::akd, a module kept apart"),
        # The EtherCAT layer naming a drive's object, imported from nowhere: written by the master, in a codec's
        # constant, in a macro's tokens.
        (
            {"ethercat/master/mod.rs": "pub struct Master;\nimpl Master { fn f(&mut self) { self.w(0x6060, 0); } }"},
            "rust: ethercat::master names 0x6060, an object of a device",
        ),
        (
            {"ethercat/sii.rs": "pub struct Identity;\npub const PARAM02: u16 = 0x3e02;\n"},
            "rust: ethercat::sii names 0x3E02, an object of a device",
        ),
        (
            {"ethercat/link/udp.rs": "pub fn g() { let _ = vec![0x60C2u16]; }\n"},
            "rust: ethercat::link::udp names 0x60C2, an object of a device",
        ),
        # A cycle among siblings of one directory.
        (
            {
                "ethercat/link/mod.rs": "pub mod udp;\npub mod raw;\n",
                "ethercat/link/udp.rs": "use super::raw::R;\npub struct U;\n",
                "ethercat/link/raw.rs": "pub struct R(super::udp::U);\n",
            },
            "rust: cycle among the modules of ethercat::link: ethercat::link::raw <-> ethercat::link::udp",
        ),
        # A module no layer names.
        ({"newthing.rs": "pub struct N;\n"}, "rust: module newthing is in no layer"),
    ],
)
def test_a_planted_rust_problem_fails(tmp_path, planted, expected):
    checked = _check(_tree(tmp_path, {**CLEAN_RUST, **planted}, CLEAN_PYTHON))
    assert checked.returncode == 1
    assert expected in checked.stderr, checked.stderr


@pytest.mark.parametrize(
    ("planted", "expected"),
    [
        ({"units.py": "from akd_ros.node import core\n"}, "python: akd_ros::units depends on akd_ros::node"),
        ({"units.py": "from . import bus\n"}, "python: akd_ros::units depends on akd_ros::bus, a layer above it"),
        (
            {"node/core.py": "from . import lifecycle\n", "node/lifecycle.py": "from .core import x\n"},
            "python: cycle among the modules of akd_ros::node: akd_ros::node::core <-> akd_ros::node::lifecycle",
        ),
    ],
)
def test_a_planted_python_problem_fails(tmp_path, planted, expected):
    checked = _check(_tree(tmp_path, CLEAN_RUST, {**CLEAN_PYTHON, **planted}))
    assert checked.returncode == 1
    assert expected in checked.stderr, checked.stderr


def test_a_file_that_does_not_parse_is_named(tmp_path):
    checked = _check(_tree(tmp_path, {**CLEAN_RUST, "ethercat/frame.rs": "pub fn f( {\n"}, CLEAN_PYTHON))
    assert checked.returncode != 0
    assert "frame.rs does not parse" in checked.stderr
