"""Running many scenarios: chunks on an executor, each chunk's records a Parquet file, resumable, with progress.

The work is a list of ``ScenarioSpec`` (evidence.sweep), cut into chunks of a fixed size in a fixed order, so
chunk k is the same specs in every run of the same sweep. A chunk's records are written to
``<out>/records/chunk-<k>.parquet`` the moment it comes back (written to a temporary name, then renamed: a
crash never leaves half a file), and a rerun skips every chunk already there: a sweep killed at any point
resumes where it stopped. Every summary is computed from those files, never from memory.

Executors (the same records either way, since ``run_scenario`` is deterministic):
- ``local`` (default): a process pool of `workers` on this machine;
- ``dask``: a dask.distributed scheduler (``--dask tcp://HOST:8786``, e.g. dask-jobqueue on Slurm), or a
  ``LocalCluster`` of `workers` single-threaded processes when no address is given.

A chunk that fails (its worker died, the pool broke) is retried up to `retries` times (dask reschedules a
task whose worker died by itself as well); one that still fails is reported by number and the run ends with
it missing, never silently dropped: rerun to fill it in.
"""

from __future__ import annotations

import json
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence, TextIO

from evidence.sweep import RECORD_FIELDS, ScenarioSpec, run_chunk
from shared.core.errors import HrcError

CHUNK = 8                   # scenarios per chunk (a file each): a lost worker costs at most this many


@dataclass
class SweepResult:
    """What a run did: chunks in all, found already done, run now, and the ones that failed for good."""

    chunks: int
    skipped: int = 0
    ran: int = 0
    failed: list[int] = field(default_factory=list)
    wall_s: float = 0.0
    startup_s: float = 0.0          # of wall_s: starting the executor (a LocalCluster's scheduler and workers)


def code_version(root: Path) -> str:
    """The code a sweep's records come from (git describe --always --dirty; "unknown" outside a checkout):
    part of its plan, so records of other code are never resumed into."""
    import subprocess

    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=root, capture_output=True, text=True,
                             timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"
    return out.stdout.strip() or "unknown"


def chunks_of(specs: Sequence[ScenarioSpec], size: int = CHUNK) -> list[list[ScenarioSpec]]:
    return [list(specs[k:k + size]) for k in range(0, len(specs), size)]


def chunk_path(out: Path, k: int) -> Path:
    return out / "records" / f"chunk-{k:05d}.parquet"


def write_chunk(out: Path, k: int, records: list[dict]) -> None:
    """A chunk's records as one Parquet file, atomically (temporary name, then rename)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = chunk_path(out, k)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pylist([{f: r[f] for f in RECORD_FIELDS} for r in records])
    tmp = path.with_suffix(".parquet.tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, path)


def read_records(out: Path) -> list[dict]:
    """Every record written under `out`, in chunk order."""
    import pyarrow.parquet as pq

    records: list[dict] = []
    for path in sorted((out / "records").glob("chunk-*.parquet")):
        records.extend(pq.read_table(path).to_pylist())
    return records


class SweepFolderError(HrcError, ValueError):
    """Another sweep's folder (``hrc sweep --against``) that holds no readable records, with what is wrong."""


def read_sweep(folder: Path) -> list[dict]:
    """The records of another sweep's folder, to compare with: SweepFolderError where it is not a folder, holds
    no records, or a chunk cannot be read or lacks a field (a file from elsewhere), naming it."""
    import pyarrow as pa

    if not folder.is_dir():
        raise SweepFolderError(f"{folder}: no such folder (a folder that hrc sweep --out wrote)")
    paths = sorted((folder / "records").glob("chunk-*.parquet"))
    if not paths:
        raise SweepFolderError(f"{folder}: no sweep records (records/chunk-*.parquet) in it")
    import pyarrow.parquet as pq

    records: list[dict] = []
    for path in paths:
        try:
            rows = pq.read_table(path).to_pylist()
        except (OSError, pa.ArrowException) as exc:
            raise SweepFolderError(f"{path}: cannot read these records: {exc}") from None
        missing = set(RECORD_FIELDS) - set(rows[0]) - {"latency"} if rows else set()   # latency: 0 before it was kept
        rows = [{"latency": 0.0} | r for r in rows]
        if missing:
            raise SweepFolderError(f"{path}: not a sweep's records (no {', '.join(sorted(missing))})")
        records.extend(rows)
    return records


def plan_of(specs: Sequence[ScenarioSpec], chunk: int, meta: dict) -> dict:
    return {"chunk": chunk, "specs": [[s.kind, s.seed, s.duration, s.strategy, list(map(list, s.overrides)),
                                       s.forecaster] + ([s.latency] if s.latency else []) for s in specs], **meta}


def plan_id(specs: Sequence[ScenarioSpec], chunk: int = CHUNK, meta: dict | None = None) -> str:
    """A short name for a sweep's plan (its hash): a folder per plan lets a tool with a fixed output folder
    resume the same run and keep apart different ones."""
    import hashlib

    text = json.dumps(plan_of(specs, chunk, meta or {}), sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:12]


def write_plan(out: Path, specs: Sequence[ScenarioSpec], chunk: int, meta: dict) -> None:
    """The sweep's plan beside its records: a rerun into the same folder must be the same sweep (else its
    chunks would mean other specs), so a different plan is refused (SweepMismatch)."""
    plan = plan_of(specs, chunk, meta)
    path = out / "plan.json"
    if path.exists():
        old = json.loads(path.read_text())
        if old != plan:
            differs = sorted(k for k in set(old) | set(plan) if old.get(k) != plan.get(k))
            raise SweepMismatch(f"{out} holds another sweep's records (plan.json differs in {', '.join(differs)}): "
                                f"give another --out, or remove that folder to start again")
        return
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(plan))


class SweepMismatch(HrcError):
    """The output folder holds the records of a different sweep."""


class Progress:
    """done/total, rate and time left: a bar redrawn in place on a terminal, a plain line now and then otherwise."""

    def __init__(self, total: int, already: int = 0, stream: TextIO | None = None, every: float = 10.0) -> None:
        self.total, self.done, self.already = total, already, already
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.started = time.perf_counter()
        self.every, self.last = every, -1e9

    def line(self) -> str:
        spent = time.perf_counter() - self.started
        new = self.done - self.already
        rate = new / spent if spent > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else float("nan")
        eta = f"{left:.0f} s left" if left == left else "time left unknown"
        return f"{self.done}/{self.total} scenarios, {rate:.2f}/s, {spent:.0f} s so far, {eta}"

    def advance(self, n: int) -> None:
        self.done += n
        now = time.perf_counter()
        if self.tty:
            width = 30
            filled = int(width * self.done / max(self.total, 1))
            self.stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {self.line()}   ")
            if self.done >= self.total:
                self.stream.write("\n")
            self.stream.flush()
        elif now - self.last >= self.every or self.done >= self.total:
            self.last = now
            print(self.line(), file=self.stream, flush=True)


def run_sweep(specs: Sequence[ScenarioSpec], out: Path, executor: str = "local", workers: int = 2,
              address: str | None = None, chunk: int = CHUNK, retries: int = 2, meta: dict | None = None,
              task: Callable[[list[ScenarioSpec]], list[dict]] = run_chunk,
              progress: Progress | None = None) -> SweepResult:
    """Run every chunk of `specs` not yet under `out`, on `executor`, writing each as it comes back."""
    write_plan(out, specs, chunk, meta or {})
    pieces = chunks_of(specs, chunk)
    todo = [k for k in range(len(pieces)) if not chunk_path(out, k).exists()]
    result = SweepResult(chunks=len(pieces), skipped=len(pieces) - len(todo))
    progress = progress or Progress(len(specs))
    waiting = set(todo)
    progress.done = progress.already = sum(len(piece) for k, piece in enumerate(pieces) if k not in waiting)
    started = time.perf_counter()
    if todo:
        run = _run_dask if executor == "dask" else _run_local
        run(pieces, todo, out, workers, address, retries, task, progress, result)
    result.wall_s = time.perf_counter() - started
    return result


def _finished(out: Path, k: int, records: list[dict], progress: Progress, result: SweepResult) -> None:
    write_chunk(out, k, records)
    result.ran += 1
    progress.advance(len(records))


def _run_local(pieces, todo, out, workers, address, retries, task, progress, result) -> None:
    """A process pool; a pool broken by a dying worker is replaced and its unfinished chunks run again."""
    tries = {k: 0 for k in todo}
    pending = list(todo)
    while pending:
        with ProcessPoolExecutor(workers) as pool:
            futures = {pool.submit(task, pieces[k]): k for k in pending}
            pending = []
            while futures:
                done, _ = wait(futures, return_when=FIRST_COMPLETED)
                for future in done:
                    k = futures.pop(future)
                    try:
                        _finished(out, k, future.result(), progress, result)
                    except BrokenProcessPool:
                        _retry(k, tries, retries, pending, result, "its worker process died")
                    except Exception as exc:           # a chunk's own error: retried, then reported
                        _retry(k, tries, retries, pending, result, f"{type(exc).__name__}: {exc}")


def _retry(k: int, tries: dict, retries: int, pending: list, result: SweepResult, why: str) -> None:
    tries[k] += 1
    if tries[k] <= retries:
        print(f"sweep: chunk {k} failed ({why}); running it again ({tries[k]}/{retries})", file=sys.stderr)
        pending.append(k)
    else:
        print(f"sweep: chunk {k} failed {tries[k]} times ({why}); left out of this run: rerun to fill it in",
              file=sys.stderr)
        result.failed.append(k)


def _run_dask(pieces, todo, out, workers, address, retries, task, progress, result) -> None:
    """dask.distributed: the given scheduler, or a LocalCluster of `workers` single-threaded processes. A task
    whose worker died is rescheduled by the scheduler; one that raised is submitted again up to `retries`."""
    import dask
    from distributed import Client, LocalCluster, as_completed

    cluster, started = None, time.perf_counter()
    if address is None:
        # a worker samples its task thread's stack every 10 ms by default (its profiler) and may watch the GIL:
        # for a pure-Python simulation that is time taken from the task, so a cluster started here does neither
        # nor wakes its event loop 50 times a second for the blocked-loop watchdog, 10 for the memory monitor:
        # each wake-up takes the GIL from the task (a sweep's workers need neither at that rate)
        dask.config.set({"distributed.worker.profile.enabled": False,
                         "distributed.admin.system-monitor.gil.enabled": False,
                         "distributed.admin.tick.interval": "1000ms",
                         "distributed.worker.memory.monitor-interval": "1000ms",
                         "distributed.admin.system-monitor.interval": "2000ms"})
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                               host="127.0.0.1", scheduler_port=0, silence_logs=40)
        address = cluster.scheduler_address
    try:
        with Client(address) as client:
            result.startup_s = time.perf_counter() - started
            tries = {k: 0 for k in todo}
            futures = {client.submit(task, pieces[k], key=f"chunk-{k}-{os.getpid()}-0", pure=False): k
                       for k in todo}
            queue = as_completed(list(futures))
            for future in queue:
                k = futures.pop(future)
                try:
                    _finished(out, k, future.result(), progress, result)
                except Exception as exc:
                    again: list[int] = []
                    _retry(k, tries, retries, again, result, f"{type(exc).__name__}: {exc}")
                    for j in again:
                        retry = client.submit(task, pieces[j], key=f"chunk-{j}-{os.getpid()}-{tries[j]}", pure=False)
                        futures[retry] = j
                        queue.add(retry)
    finally:
        if cluster is not None:
            cluster.close()
