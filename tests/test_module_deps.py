"""scripts/module_deps.py sees what it checks: a cycle and a dependency up a layer planted in a scratch tree fail it,
wherever in the code they are written, and text that only looks like code (strings, comments, doc comments, tests)
does not."""

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
//! Module docs may name crate::master::Master: docs link anywhere.
/// So may an item's: [`crate::master::Master`].
pub const CONTINUED: &str = "a string continued \
    over a line, with a quote after a word: header\" and crate::master::Master inside";
pub const RAW: &str = r#"a raw string with "quotes" and crate::master::Master"#;
pub const QUOTE: char = '"';
pub fn lifetime<'a>(s: &'a str) -> &'a str { s }
/* a block comment naming crate::master::Master */
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


CLEAN_RUST = {
    "lib.rs": "pub mod frame;\npub mod sii;\npub mod error;\npub mod link;\npub mod master;\npub mod sim;\n",
    "frame.rs": TRICKY + "pub struct Frame;\n#[cfg(test)]\nmod tests {\n    use crate::master::Master;\n}\n",
    "sii.rs": "use crate::frame::Frame;\npub struct Identity(pub Frame);\n",
    "error.rs": "pub enum Error { Sii(crate::sii::Identity) }\n",
    "link/mod.rs": "pub mod udp;\nuse crate::error::Error;\npub fn f(_: Error) {}\n",
    "link/udp.rs": "use super::f;\npub fn g() { let _ = f; }\n",
    "master/mod.rs": "use crate::{link::udp::g, frame::{self, Frame}};\npub struct Master(Frame);\n",
    "sim/mod.rs": 'pub fn serve() { crate::link::udp::g(); let _ = format!("{:?}", 1); }\n',
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
            {"frame.rs": TRICKY + "use crate::sii::Identity;\npub struct Frame;\n"},
            "rust: cycle among the modules of the crate: frame <-> sii",
        ),
        # A codec naming the master, up two layers, in a function body and in a macro's tokens.
        (
            {"frame.rs": TRICKY + "pub struct Frame;\npub fn f() { let _ = crate::master::Master; }\n"},
            "rust: frame depends on master, a layer above it",
        ),
        (
            {"frame.rs": TRICKY + 'pub struct Frame;\npub fn f() { println!("{:?}", crate::link::f); }\n'},
            "rust: frame depends on link, a layer above it",
        ),
        # The virtual AKD reaching into the master, one layer but kept apart.
        ({"sim/mod.rs": "use crate::master::Master;\n"}, "rust: sim depends on master, a module kept apart from it"),
        # A cycle among siblings of one directory.
        (
            {
                "link/mod.rs": "pub mod udp;\npub mod raw;\n",
                "link/udp.rs": "use super::raw::R;\npub struct U;\n",
                "link/raw.rs": "pub struct R(super::udp::U);\n",
            },
            "rust: cycle among the modules of link: link::raw <-> link::udp",
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
    checked = _check(_tree(tmp_path, {**CLEAN_RUST, "frame.rs": "pub fn f( {\n"}, CLEAN_PYTHON))
    assert checked.returncode != 0
    assert "frame.rs does not parse" in checked.stderr
