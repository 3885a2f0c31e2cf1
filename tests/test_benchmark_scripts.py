"""The benchmark scripts as a contributor runs them: ``--help`` says how, and runs nothing
(benchmarks/dense.py ran its whole benchmark; plain_opencv.py raised TypeError)."""

import subprocess
import sys

import pytest

from .conftest import REPO

SCRIPTS = sorted(p.name for p in (REPO / "benchmarks").glob("*.py") if p.name != "bench_cli.py")


@pytest.mark.parametrize("name", SCRIPTS)
def test_help_prints_the_usage_and_runs_nothing(name):
    proc = subprocess.run([sys.executable, str(REPO / "benchmarks" / name), "--help"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"usage: {name} ")
    assert proc.stderr == ""
    assert "|---|" not in proc.stdout  # no table: nothing was measured
