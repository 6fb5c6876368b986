"""The hrc command line and the in-process demo of the paper's experiment (`hrc demo --sim`): the tests that start a
process or a network namespace (the rest, in-process, are in
tests/tools/test_cli_and_demo.py)."""

import json
import subprocess
import sys


def hrc(*args):
    return subprocess.run([sys.executable, "-m", "tools.cli", *args], capture_output=True, text=True, timeout=300)


def test_demo_runs_and_prints_a_json_summary(tmp_path):
    out = hrc("demo", "--sim", "--duration", "3", "--quiet", "--out", str(tmp_path))
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout.strip().splitlines()[-1])
    assert summary["violations"] == 0 and summary["cycles"] == 300
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
