"""Generated misuse for long: the Hypothesis state machine of tests/test_node_generated_misuse.py (goals of both
actions, ~/joint_trajectory, set-points, homing, output writes, cancels and bursts of service calls against the
six-axis virtual robot, every invariant checked after every step) run with a budget of hours instead of the suite's
minute. Prints the cases tried (steps by rule, examples) and how long they took; exit status 0 when every invariant
held, else pytest's, with the failing sequence Hypothesis shrank to (see docs/develop/soak.md).

    .venv/bin/python bench/misuse_soak.py --examples 3000 --steps 12
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TEST = ROOT / "tests" / "test_node_generated_misuse.py"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--examples", type=int, default=3000, help="Hypothesis examples (default 3000)")
    parser.add_argument("--steps", type=int, default=12, help="steps per example (default 12)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        cases = Path(folder) / "cases.json"
        env = dict(
            os.environ,
            AKD_MISUSE_EXAMPLES=str(args.examples),
            AKD_MISUSE_STEPS=str(args.steps),
            AKD_MISUSE_CASES=str(cases),
            # Domains no test module uses: the soak runs beside the suite on a shared machine.
            AKD_MISUSE_DOMAINS="5 10",
        )
        pytest = [sys.executable, "-m", "pytest", str(TEST), "-q", "-p", "no:cacheprovider"]
        status = subprocess.run(pytest, cwd=ROOT, env=env, check=False).returncode
        if cases.exists():
            tried = json.loads(cases.read_text())
            by_rule = ", ".join(f"{rule} {count}" for rule, count in sorted(tried["by_rule"].items()))
            print(
                f"misuse soak: {tried['steps']} steps in {tried['examples']} examples over {tried['seconds']} s "
                f"({by_rule}): {'every invariant held' if status == 0 else 'FAILED'}"
            )
    return status


if __name__ == "__main__":
    sys.exit(main())
