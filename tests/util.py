"""Helpers the tests share: a free loopback port, `hrc` run in-process, a benchmark script as a module, and
the private network namespace the multi-process tests need (they skip, saying why and what covers the same
behaviour, where it cannot be made)."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from shared.safety.parameters import SsmParameters
from tools.cell import namespace_reason
from tools.launch import free_port

__all__ = ["LAID_OUT_SSM", "ROOT", "CliRun", "free_port", "load_bench", "namespace_reason", "require_namespace", "run_hrc",
           "stopped"]

ROOT = Path(__file__).resolve().parents[1]          # the repository: deploy/, bench/, tests/data/
BENCH = ROOT / "bench"
# The shipped human model with T_r 0.1 s, shipped until session 81 (now 0.05 s: the cell's own chain, the data's age
# counted on the person's side). The planning tests' cases (a robot held beside a person standing, a way that waits
# for them) were laid out with it: with a shorter T_r the same person holds the robot less, and what they test does
# not depend on its value.
LAID_OUT_SSM = SsmParameters(reaction_time=0.1)


def load_bench(name: str):
    """A benchmark script of bench/ (not a package) as a module, to test its functions directly."""
    spec = importlib.util.spec_from_file_location(f"{name}_bench", BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def require_namespace(covered_by: str) -> None:
    """Skip the calling test, printing why, when no private network namespace can be made."""
    reason = namespace_reason()
    if reason:
        print(f"SKIP: no private network namespace ({reason}); {covered_by}")
        pytest.skip(reason)


@dataclass
class CliRun:
    """What `hrc` printed and returned, as subprocess.CompletedProcess names it."""

    returncode: int
    stdout: str
    stderr: str


def run_hrc(*args: str) -> CliRun:
    """`hrc ARGS` in this process, through tools.cli.main(argv): its exit code (argparse's SystemExit too)
    and what it printed. An exception it lets escape fails the calling test, as a traceback would."""
    from tools.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return CliRun(int(code or 0), out.getvalue(), err.getvalue())


@contextlib.contextmanager
def stopped(proc: subprocess.Popen):
    """A child process this test started, ended by its PID however the test ends: killed and reaped if it is
    still there (a test that ends it on purpose, SIGTERM, asserts its exit code itself)."""
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
