"""The scaler's silences in a run (tools.silences): where a SYNC passed without a new command, and whose silence."""

import numpy as np
import pytest

from tools.silences import GAP_PERIODS, LISTED, said, scaler_silences, stale_stops

PERIOD = 0.01


def ticks_every_period(t_end: float, t0: float = 100.0) -> np.ndarray:
    return t0 + np.arange(0.0, t_end, PERIOD)


def test_a_scaler_on_time_has_no_silence_and_nothing_is_said():
    ticks = ticks_every_period(2.0) + np.random.default_rng(1).uniform(0.0, 0.004, 200)   # jitter under a period
    silences = scaler_silences(ticks, np.full(ticks.size, 200.0), ticks - 0.0005, PERIOD, 100.0)
    assert silences == {"count": 0, "longest": []} and said(silences) is None


def test_a_silence_while_the_driver_published_states_is_the_scalers_own():
    """The recorded case (session 60, a stale_command stop): ticks at 3.447 and 3.488 s, the driver's states at
    3.456, 3.480 and 3.484 s meanwhile."""
    ticks = np.array([3.425, 3.4387, 3.447, 3.4884, 3.4941]) + 100.0
    states = np.array([3.4246, 3.438, 3.4463, 3.4563, 3.4796, 3.4838, 3.4935]) + 100.0
    silences = scaler_silences(ticks, np.array([210.0, 190.0, 250.0, 300.0, 180.0]), states, PERIOD, 100.0)
    assert silences["count"] == 1
    t, gap, step, states_inside, driver = silences["longest"][0]
    assert t == pytest.approx(3.447) and gap == pytest.approx(41.4) and step == pytest.approx(0.25)
    assert states_inside == 3 and driver == pytest.approx(23.3)
    line = said(silences)
    assert "41 ms at t=3.45 s" in line and "3 joint state(s)" in line and "did not tick on them" in line


def test_a_silence_with_the_driver_silent_too_says_so():
    ticks = np.concatenate([ticks_every_period(1.0), [100.0 + 1.06], 100.0 + 1.07 + np.arange(0.0, 0.5, PERIOD)])
    states = ticks[ticks != 100.0 + 1.06] - 0.001            # no state between the tick at 0.99 and the one at 1.06 s
    states = states[(states < 100.99) | (states > 101.06)]
    silences = scaler_silences(ticks, np.full(ticks.size, 200.0), states, PERIOD, 100.0)
    assert silences["count"] == 1 and silences["longest"][0][3] == 0
    assert "no joint state meanwhile either" in said(silences)


def test_a_gap_just_under_the_threshold_is_no_silence_and_the_longest_come_first():
    gap = GAP_PERIODS * PERIOD
    ticks = [0.0, 0.99 * gap, 0.99 * gap + 1.01 * gap]
    for k in range(LISTED + 3):            # more silences than are listed, growing
        ticks.append(ticks[-1] + (3.0 + k) * PERIOD)
    ticks = np.array(ticks)
    silences = scaler_silences(ticks, np.zeros(ticks.size), np.zeros(0), PERIOD, 0.0)
    assert silences["count"] == 1 + LISTED + 3 and len(silences["longest"]) == LISTED
    gaps = [row[1] for row in silences["longest"]]
    assert gaps == sorted(gaps, reverse=True) and gaps[0] == pytest.approx((3.0 + LISTED + 2) * PERIOD * 1e3)


def test_ticks_and_step_times_must_pair():
    with pytest.raises(ValueError, match="3 tick stamps but 2 step times"):
        scaler_silences(np.zeros(3), np.zeros(2), np.zeros(0), PERIOD, 0.0)


def test_every_report_says_the_scalers_silences():
    """tools.report.analyse: a run whose scaler skipped ticks for 45 ms while the driver went on."""
    from evidence.scenarios import Q_START
    from shared.config import CellConfig
    from shared.robot.model import default_robot
    from shared.wire.messages import JointState, ScalerStatus
    from tools.report import Recording, analyse

    rec = Recording(t0=100.0)
    for k in range(60):
        t = 100.0 + PERIOD * k
        rec.joint_states.append(JointState(q=Q_START, qd=np.zeros(6), drive_state="enabled", enabled=True, fault=False,
                                           stamp=t - 0.0005))
        if not 20 < k < 25:                   # no tick for the SYNCs 21-24
            rec.statuses.append(ScalerStatus(s=0.0, alpha=1.0, safe_alpha=1.0, beta=False, q_command=Q_START,
                                             trajectory_version=1, status="running", method="piqp",
                                             min_separation=None, min_margin=None, compute_us=80.0, stamp=t))
    summary, _ = analyse(default_robot(), CellConfig(), rec)
    assert summary["scaler_silences"] == {"count": 1, "longest": [[0.2, 50.0, 0.08, 5, 10.0]], "stale_stops": []}


def test_a_stop_for_commands_that_were_sent_but_not_taken_is_no_silence_of_the_scaler():
    """The recorded case (this session, a stale_command with no silence): ticks at 9.797, 9.815, 9.823 and
    9.841 s, the driver's stop at 9.855 s 'no command for 56 ms': three commands had not reached it."""
    commands = np.array([9.769810, 9.776940, 9.787192, 9.797071, 9.815071, 9.823056, 9.841383, 9.865466]) + 100.0
    (row,) = stale_stops([(100.0 + 9.854887, 0.056)], commands, 100.0)
    assert row[:3] == [9.855, 56.0, 3] and row[3] == pytest.approx(39.8, abs=0.05)
    line = said({"count": 0, "longest": [], "stale_stops": [row]})
    assert line.startswith("the driver stopped at t=9.86 s without a command for 56 ms: the scaler had published 3")
    # none published meanwhile: the scaler's own silence
    (quiet,) = stale_stops([(100.0 + 9.854887, 0.056)], commands[commands < 100.0 + 9.80], 100.0)
    assert quiet[2] == 0 and quiet[3] is None
    assert "the scaler had published none meanwhile" in said({"count": 1, "longest": [[9.797, 58.0, 0.3, 5, 12.0]],
                                                              "stale_stops": [quiet]})
