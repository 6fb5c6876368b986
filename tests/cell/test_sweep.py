"""Sweeps across processes: the local pool and a Dask LocalCluster give the same records; a sweep killed
mid-run resumes and gives the same summary as one that ran through; a chunk whose worker process dies is run
again (the pure parts are in tests/tools/test_sweep.py)."""

import functools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from evidence.sweep import ScenarioSpec, run_chunk
from tests.tools.test_sweep import same
from tests.util import ROOT
from tools import sweep

SPECS = [ScenarioSpec(kind, seed, 1.0, strategy) for kind in ("standing", "crossing") for seed in (0, 1)
         for strategy in ("zones", "scale_only")]


def quiet() -> sweep.Progress:
    return sweep.Progress(len(SPECS), stream=open(os.devnull, "w"), every=1e9)


def test_the_local_pool_and_dask_give_the_same_records(tmp_path):
    local = sweep.run_sweep(SPECS, tmp_path / "local", workers=2, chunk=3, progress=quiet())
    dask = sweep.run_sweep(SPECS, tmp_path / "dask", executor="dask", workers=2, chunk=3, progress=quiet())
    assert local.ran == dask.ran == 3 and not local.failed and not dask.failed
    records = sweep.read_records(tmp_path / "local")
    assert len(records) == len(SPECS) and same(records, sweep.read_records(tmp_path / "dask"))
    assert [(r["kind"], r["seed"], r["strategy"]) for r in records] == [(s.kind, s.seed, s.strategy) for s in SPECS]


def die_once(marker: str, specs: list[ScenarioSpec]) -> list[dict]:
    """A chunk's task whose process dies the first time it is given the chunk that holds seed 1 of standing."""
    if any(s.kind == "standing" and s.seed == 1 for s in specs) and not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(1)
    return run_chunk(specs)


@pytest.mark.parametrize("executor", ["local", "dask"])
def test_a_chunk_whose_worker_dies_is_run_again(tmp_path, executor):
    marker = tmp_path / "died"
    done = sweep.run_sweep(SPECS, tmp_path / "out", executor=executor, workers=2, chunk=2, progress=quiet(),
                           task=functools.partial(die_once, str(marker)))
    assert marker.exists(), "the worker was meant to die once"
    assert not done.failed and done.ran == 4
    assert same(sweep.read_records(tmp_path / "out"), run_chunk(SPECS))


def hrc_sweep(out: Path) -> list[str]:
    return [sys.executable, "-m", "tools.cli", "sweep", "--set", "ssm.reaction_time=0.1,0.2", "--scenarios", "3",
            "--kinds", "standing", "--duration", "1.5", "--strategies", "scale_only,zones", "--chunk", "1",
            "--workers", "1", "--out", str(out)]


def test_a_killed_sweep_resumes_and_gives_the_same_summary(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    through = subprocess.run(hrc_sweep(tmp_path / "through"), cwd=ROOT, env=env, capture_output=True, text=True,
                             timeout=300)
    assert through.returncode == 0, through.stderr[-2000:]
    killed = tmp_path / "killed"
    proc = subprocess.Popen(hrc_sweep(killed), cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while len(list((killed / "records").glob("chunk-*.parquet"))) < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)                       # the sweep and its pool, mid-run
        proc.wait(10)
    left = len(list((killed / "records").glob("chunk-*.parquet")))
    assert 3 <= left < 12, f"{left} chunks before the kill: the test did not interrupt the sweep"
    again = subprocess.run(hrc_sweep(killed), cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr[-2000:]
    assert f"{left} already there" in again.stdout
    def timeless(value):       # the figures but for the compute they cost, overall and in every kind
        if isinstance(value, dict):
            return {k: timeless(v) for k, v in value.items() if k != "wall_s_per_scenario"}
        return [timeless(v) for v in value] if isinstance(value, list) else value

    summary = lambda folder: timeless(json.loads((folder / "summary.json").read_text())["points"])
    assert summary(killed) == summary(tmp_path / "through")
    assert (killed / "sweep-ssm.reaction_time.png").read_bytes()[:4] == b"\x89PNG"
