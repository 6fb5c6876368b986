"""The people's forecast as a function of time (PeopleForecast.at) and bench/forecast.py's command line and: the tests
that start a process or a network namespace (the rest, in-process, are in
tests/evidence/test_forecast_bench.py)."""

import json
import subprocess
import sys

from tests.util import ROOT


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "bench" / "forecast.py"), *args],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)


def test_bad_arguments_are_refused_with_a_reason(tmp_path):
    assert "--horizons" in run("--horizons", "1,x").stderr
    assert "--kinds: unknown or none ['nope']" in run("--kinds", "nope").stderr
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    done = run("--kinds", "", "--motion", str(broken))
    assert done.returncode == 2 and "--motion" in done.stderr and "broken.json" in done.stderr


def test_kinds_and_motion_files_come_out_per_forecaster_and_horizon():
    done = run("--seeds", "1", "--duration", "3", "--kinds", "crossing", "--horizons", "0.5,1",
               "--motion", str(ROOT / "docs" / "motions" / "reach_stays.json"))
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(result["errors"]) == {"crossing", "reach_stays.json"}
    for per_forecaster in result["errors"].values():
        assert set(per_forecaster) == {"still", "constant velocity", "constant velocity, every part"}
        for horizons in per_forecaster.values():
            assert set(horizons) == {"0.5", "1.0"}
            assert all(0.0 <= mean and 0.0 <= p95 for mean, p95 in horizons.values())


def test_compare_takes_a_forecaster_for_full_and_names_it(tmp_path):
    args = ["--scenarios", "1", "--kinds", "standing", "--duration", "2", "--workers", "1", "--out", str(tmp_path)]

    def full(*more):
        done = subprocess.run([sys.executable, str(ROOT / "bench" / "compare.py"), *args, *more],
                              capture_output=True, text=True, timeout=300, cwd=ROOT)
        assert done.returncode == 0, done.stderr[-2000:]
        result = json.loads(done.stdout.strip().splitlines()[-1])
        return result["forecaster"], result["kinds"]["standing"]["full"]

    named, same = full("--forecaster", "shared.planning.forecast:ConstantVelocity")
    assert named == "shared.planning.forecast:ConstantVelocity" and same == full()[1]   # the default, by name
    refused = subprocess.run([sys.executable, str(ROOT / "bench" / "compare.py"), *args, "--forecaster", "nope"],
                             capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert refused.returncode == 2 and "--forecaster" in refused.stderr and "module:attribute" in refused.stderr
