"""The robot end, the tracker, the scaling layer and the independent monitor as five processes (emulator,
robot driver, tracker_ingest, scaler, safety_monitor) over Zenoh and CAN, in a private network namespace. Raw human
poses go through
tracker_ingest at 240 Hz: a trajectory is followed to its goal at the nominal speed when no one is near,
a silent tracker (its raw stream stops) brings the robot to a standstill, a person standing beside the
path slows the robot down without stopping it, and the monitor, having checked every measured joint
state, counts no violation."""

import pytest

from tests.cell.test_hil import run_harness
from tests.util import require_namespace
from tools.cell import unshare_flags

# system_replan (planner as a fourth process; an arm steps across the path) is in the harness but not run
# here yet: the planner replans around the arm and the robot stays safe, but it stalls next to the arm
# instead of reaching the goal (see the issue notes). `python tests/hil/harness.py --with-planner` runs it.
SCENARIOS = ["system_goal", "system_stale_humans", "system_near_human", "garbage_everywhere", "monitor_report"]


@pytest.fixture(scope="module")
def results():
    require_namespace("the scaler core is covered by tests/scaling/test_scaling_layer.py")
    return run_harness(["unshare", unshare_flags()],
                       ["--interface", "udp_multicast", "--with-tracker", "--scenarios", *SCENARIOS])


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_three_processes(results, scenario):
    print(f"{scenario}: {results[scenario]}")
    assert results[scenario]["ok"], results[scenario]
