"""The demo's person feed as a process of its own (tools.feed): it waits for tracker_ingest, starts at the t0 it
is given, the scripted person as they stand at the start shown for its lead-in before it, sends the motion at its
rate with each sample stamped with the moment it shows, and on SIGTERM stops and writes its figures; a bad motion
file is a clear error and nothing is sent."""

import json
import subprocess
import sys
import time

from evidence.scenarios import paper_phases
from shared.transport.zenoh_session import open_session
from shared.wire.keys import KeySpace
from shared.wire.messages import HumanRaw, decode
from tests.util import ROOT, free_port
from tools.actors import LEAD_IN, lead_in_time
from tools.feed import READY

KEYS = KeySpace("t/feed")


def _feed(endpoint: str, stats, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tools.feed", "--connect", endpoint, "--prefix", KEYS.prefix,
                             "--stats", str(stats), *extra], cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_sends_the_motion_from_t0_and_reports_what_it_sent(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = open_session("peer", listen=[endpoint])
    token = session.liveliness().declare_token(KEYS.alive("tracker_ingest"))     # it waits for the tracker
    samples = []
    sub = session.declare_subscriber(KEYS.human_raw, lambda s: samples.append(decode(s.payload.to_bytes(), HumanRaw)))
    proc = _feed(endpoint, tmp_path / "stats.json", "--phase-length", "2.0")
    try:
        assert proc.stdout.readline().strip() == READY
        time.sleep(0.3)
        assert not samples                                           # nothing before its start
        t0 = time.monotonic() + lead_in_time(120.0) + 0.05       # a start ahead of the lead-in, as hrc demo gives
        proc.stdin.write(f"{t0!r}\n")
        proc.stdin.close()
        said = proc.stdout.readline()
        assert "sending at 120.0 Hz" in said and ("SCHED_FIFO 40" in said or "normal scheduling" in said), said
        time.sleep(1.5)
        proc.terminate()                                             # by its PID
        assert proc.wait(10) == 0, proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        sub.undeclare()
        token.undeclare()
        session.close()
    stats = json.loads((tmp_path / "stats.json").read_text())
    assert stats["rate_hz"] == 120.0 and stats["sent"] >= len(samples) > 100
    assert 0.0 <= stats["late_ms_p99"] <= stats["late_ms_max"] + 0.1        # how late it woke, said
    human = paper_phases(2.0)
    lead = [s for s in samples if s.sample_time < t0]            # the person standing at the start, seen before it
    assert 1 <= len(lead) <= LEAD_IN, [s.sample_time - t0 for s in lead]
    for s in lead:
        before = (t0 - s.sample_time) * 120
        assert abs(before - round(before)) < 1e-6 and 1 <= round(before) <= LEAD_IN
        assert (s.segments == human.at(0.0).segments).all()
    samples = samples[len(lead):]
    times = [s.sample_time - t0 for s in samples]
    assert times == sorted(times) and 0.0 <= times[0] < 0.05
    frames = [(b - a) * 120 for a, b in zip(times, times[1:])]
    assert all(abs(f - round(f)) < 1e-6 and f > 0.5 for f in frames)      # whole frames, each once, skipped or not
    expected = human.at(times[50])
    assert (samples[50].segments == expected.segments).all()          # the script's person at that moment


def test_a_bad_motion_file_is_a_clear_error(tmp_path):
    bad = tmp_path / "motion.csv"
    bad.write_text("t,person\n0.0,not-a-number\n")
    proc = _feed(f"tcp/127.0.0.1:{free_port()}", tmp_path / "stats.json", "--human", str(bad))
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "human_feed: error:" in err and "Traceback" not in err, err
    assert not (tmp_path / "stats.json").exists()


def test_a_start_that_is_not_a_time_is_refused(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = open_session("peer", listen=[endpoint])
    token = session.liveliness().declare_token(KEYS.alive("tracker_ingest"))
    proc = _feed(endpoint, tmp_path / "stats.json")
    try:
        assert proc.stdout.readline().strip() == READY
        out, err = proc.communicate("soon\n", timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        token.undeclare()
        session.close()
    assert proc.returncode == 2 and "'soon'" in err and "Traceback" not in err, err


def test_a_latency_outside_what_the_cell_takes_is_refused_before_anything_starts(tmp_path):
    proc = _feed(f"tcp/127.0.0.1:{free_port()}", tmp_path / "stats.json", "--latency", "0.7")
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "--latency" in err and "stale" in err and "Traceback" not in err, err
    assert READY not in out and not (tmp_path / "stats.json").exists()
