"""bench/run.py, the benchmark suite's runner, on small scripts of the tests' own: what each section's script gave is
what RESULTS.md says (its table, what it could not measure), a missing, failing or hung script is said so, a skipped
section is said skipped, and the exit status is 1 whenever a figure could not be measured. No timing is judged."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
sys.path.insert(0, str(BENCH))

spec = importlib.util.spec_from_file_location("bench_run", BENCH / "run.py")
runner = importlib.util.module_from_spec(spec)
spec.loader.exec_module(runner)

SCRIPT = f"""
import argparse, sys
sys.path.insert(0, {str(BENCH)!r})
from figures import Figures, json_argument
parser = argparse.ArgumentParser()
parser.add_argument("--missing")
json_argument(parser)
args = parser.parse_args()
figures = Figures("fake.py", "a fake section", args)
figures.table("Fake rows", [{{"name": "first", "p50 µs": 1.25}}, {{"name": "second", "p50 µs": 250.0}}])
figures.table("Raw", [{{"samples": list(range(50)), "load": [0.5, 1.0, 1.5]}}])
figures.distribution("fake samples", {{"fake": [(1.0, 5), (2.0, 3), (4.0, 2)]}})
if args.missing:
    figures.missing(args.missing)
sys.exit(figures.finish())
"""


@pytest.fixture
def suite(tmp_path, monkeypatch):
    """run.py with its folder and sections replaced: `sections` of (script name, arguments, limit s) to set."""
    (tmp_path / "results").mkdir()
    (tmp_path / "fake.py").write_text(SCRIPT)
    (tmp_path / "hangs.py").write_text("import time\ntime.sleep(60)\n")
    (tmp_path / "crashes.py").write_text("import sys\nsys.exit('crashes: on purpose')\n")
    monkeypatch.setattr(runner, "BENCH", tmp_path)
    monkeypatch.setattr(runner, "RESULTS", tmp_path / "results")

    def run(sections: dict, *options: str) -> tuple[int, str]:
        monkeypatch.setattr(runner, "SECTIONS", {name: (argv, limit) for name, (argv, limit) in sections.items()})
        monkeypatch.setattr(runner, "TITLES", {name: f"Section {name}" for name in sections})
        monkeypatch.setattr(sys, "argv", ["run.py", *options])
        return runner.main(), (tmp_path / "RESULTS.md").read_text()

    run.folder = tmp_path
    return run


def test_a_section_that_measured_everything_is_rendered_and_the_run_exits_0(suite):
    code, text = suite({"fake": (["fake.py"], 60)})
    assert code == 0
    assert "| fake | measured |" in text
    assert "| first | 1.25 |" in text and "| second | 250 |" in text
    assert "| (50 values) | 0.50/1.00/1.50 |" in text  # a script's raw samples are counted, not printed
    assert (suite.folder / "results.png").stat().st_size > 0
    assert (suite.folder / "results" / "fake.log").exists()


def test_a_figure_the_script_could_not_measure_is_named_and_the_run_exits_1(suite):
    code, text = suite({"fake": (["fake.py", "--missing", "the peer: not installed"], 60)})
    assert code == 1
    assert "| fake | partly measured |" in text
    assert "- the peer: not installed" in text
    assert "| first | 1.25 |" in text


def test_a_missing_script_is_not_measured_and_the_run_exits_1(suite):
    code, text = suite({"fake": (["fake.py"], 60), "absent": (["absent.py"], 60)})
    assert code == 1
    assert "**not measured: bench/absent.py missing**" in text
    assert "| fake | measured |" in text


def test_a_skipped_section_is_said_skipped_and_does_not_fail_the_run(suite):
    code, text = suite({"fake": (["fake.py"], 60), "absent": (["absent.py"], 60)}, "--skip", "absent")
    assert code == 0
    assert "| absent | skipped |" in text and "**skipped (--skip)**" in text


def test_a_crashing_or_hung_script_is_not_measured_with_why(suite):
    code, text = suite({"crashes": (["crashes.py"], 60), "hangs": (["hangs.py"], 1)})
    assert code == 1
    assert "not measured: exit 1: crashes: on purpose" in text
    assert "not measured: ended after the 1 s it may take" in text


def test_render_writes_the_last_run_again_without_running(suite):
    suite({"fake": (["fake.py"], 60)})
    (suite.folder / "fake.py").unlink()
    code, text = suite({"fake": (["fake.py"], 60)}, "--render")
    assert code == 0 and "| first | 1.25 |" in text


def test_again_runs_the_sections_named_and_keeps_the_last_runs_others(suite):
    sections = {"fake": (["fake.py"], 60), "other": (["crashes.py"], 60)}
    code, _ = suite(sections)
    assert code == 1
    (suite.folder / "crashes.py").write_text(SCRIPT)
    (suite.folder / "fake.py").unlink()  # kept from the first run, never run again
    code, text = suite(sections, "--again", "other")
    assert code == 0, text
    assert "| fake | measured |" in text and "| other | measured |" in text
    assert "Run again on their own" in text and "kept from the run above: other" in text


def test_an_unknown_section_to_skip_is_refused_naming_the_sections(suite, capsys):
    with pytest.raises(SystemExit) as exit_:
        suite({"fake": (["fake.py"], 60)}, "--skip", "nope")
    assert exit_.value.code == 2
    assert "no section nope; the sections: fake" in capsys.readouterr().err


@pytest.mark.parametrize("script", sorted({argv[0] for argv, _ in runner.SECTIONS.values()}))
def test_every_sections_script_starts(script):
    """Each script run.py runs imports and parses its options (--help): a script broken by a change elsewhere (a name
    it imports from another bench script, say) fails here, not an hour into a benchmark run."""
    done = subprocess.run([sys.executable, str(BENCH / script), "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
