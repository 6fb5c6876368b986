"""The independent monitor: hand-checked cases, and cross-checks against the scaling layer's kernels."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from evidence.scenarios import Q_GOAL, Q_START, paper_phases
from evidence.sim import run_shuttle
from shared.config import CellConfig
from shared.core.humans import HumanCapsules
from shared.robot.model import default_robot
from shared.safety.monitor import SafetyMonitor
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import pair_ssm

ROBOT = default_robot()
SSM = SsmParameters()
MONITOR = SafetyMonitor(ROBOT, SSM)


def test_nobody_no_violation():
    assert MONITOR.check(Q_START, np.ones(6), HumanCapsules.empty()).violations == []


def test_a_fast_link_next_to_a_person_is_a_violation_and_a_still_one_is_not():
    q = Q_START
    points, jac = ROBOT.capsule_kinematics(q)
    qd = np.array([-1.5, 0, 0, 0, 0, 0])                     # joint 1 sweeping
    heading = jac[-1, 0] @ qd
    flange = points[-1, 0]
    ahead = flange + 0.25 * heading / np.linalg.norm(heading)
    person = HumanCapsules.from_arrays([[ahead, ahead + [0, 0, 0.3]]], [0.05], np.zeros((1, 2, 3)), [True])
    moving = MONITOR.check(q, qd, person)
    assert any(v.kind == "speed" for v in moving.violations)
    still = MONITOR.check(q, np.zeros(6), person)
    assert not any(v.kind == "speed" for v in still.violations)
    close = HumanCapsules.from_arrays([[flange + [0, 0, 0.1], flange + [0, 0, 0.4]]], [0.05], np.zeros((1, 2, 3)),
                                      [True])
    up = np.linalg.lstsq(jac[-1, 0], np.array([0, 0, 0.3]), rcond=None)[0]      # the flange rising into it
    assert any(v.kind == "separation" for v in MONITOR.check(q, up, close).violations)
    # a person who walks into a robot at rest is not a separation violation: SSM governs the robot's motion
    assert not MONITOR.check(q, np.zeros(6), close).violations


@settings(max_examples=40)
@given(st.integers(0, 2 ** 31 - 1))
def test_agrees_with_the_scaling_kernels(seed):
    """coal separations equal the compiled kernel's; the closest point's approach speed never exceeds
    the scaling layer's end-point bound (so a command the scaler allows, the monitor allows)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(ROBOT.limits.lower * 0.8, ROBOT.limits.upper * 0.8)
    qd = rng.normal(size=6)
    m = 3
    centre = rng.uniform([-1.0, -1.0, 0.2], [1.0, 1.0, 1.4], size=(m, 1, 3))
    humans = HumanCapsules.from_arrays(centre + rng.normal(scale=0.2, size=(m, 2, 3)), rng.uniform(0.03, 0.15, m),
                                       rng.normal(size=(m, 2, 3)), [True] * m)
    points, jac = ROBOT.capsule_kinematics(q)
    kernel = pair_ssm(points, ROBOT.radii, jac @ qd, humans, SSM, SSM.stop_of(qd, ROBOT.limits.velocity))
    # overlapping capsules are a separation violation to both; coal's penetration witness points give
    # no meaningful direction there, so the speed comparison is for separated capsules
    assume(float(kernel.distance.min()) > 1e-4)
    result = MONITOR.check(q, qd, humans)
    assert result.min_separation == pytest.approx(float(kernel.distance.min()), abs=1e-6)
    assert result.min_margin >= float(kernel.margin.min()) - 1e-6


@settings(max_examples=60)
@given(st.integers(0, 2 ** 31 - 1))
def test_in_penetration_the_monitor_sees_the_same_direction_as_the_scaling_kernels(seed):
    """A person who walked into a link (capsules overlap, axes apart): a link moving out of them is not
    approaching. Found by 1000 random walks: coal's penetration witness points point from the human into
    the robot, and the monitor read a link backing away as approaching (13 false violations)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(ROBOT.limits.lower * 0.8, ROBOT.limits.upper * 0.8)
    qd = rng.normal(size=6)
    points, jac = ROBOT.capsule_kinematics(q)
    link = int(rng.integers(1, len(ROBOT.radii)))
    axis_point = points[link, 0] + rng.uniform(0.2, 0.8) * (points[link, 1] - points[link, 0])
    away = rng.normal(size=3)
    away /= np.linalg.norm(away)
    radius = 0.08
    overlap = rng.uniform(0.005, 0.03)
    centre = axis_point + away * (ROBOT.radii[link] + radius - overlap)
    humans = HumanCapsules.from_arrays(np.array([[centre, centre + 1e-3 * away]]), [radius], np.zeros((1, 2, 3)),
                                       [True])
    kernel = pair_ssm(points, ROBOT.radii, jac @ qd, humans, SSM, SSM.stop_of(qd, ROBOT.limits.velocity))
    assume(float(kernel.distance[link, 0]) < -1e-3)
    result = MONITOR.check(q, qd, humans)
    for v in result.violations:
        i = ROBOT.link_names.index(v.link)
        # the closest point never approaches faster than the kernel's end-point bound says
        assert v.approach_speed <= kernel.robot_speed[i, v.capsule] + 1e-6, (v, kernel.robot_speed[i, v.capsule])
    flipped = MONITOR.check(q, -qd, humans)
    approaching = {(v.link, v.capsule) for v in result.violations if v.kind == "separation"}
    backing = {(v.link, v.capsule) for v in flipped.violations if v.kind == "separation"}
    assert not (approaching & backing), "a link cannot approach a person both ways at once"


def test_every_command_of_the_paper_phases_passes_the_independent_monitor():
    result = run_shuttle(ROBOT, CellConfig(), paper_phases(6.0), Q_START, Q_GOAL, 24.0)
    human = paper_phases(6.0)
    bad = [(r.t, MONITOR.check(r.step.q_command, r.step.qd_command, human.at(r.t)).violations)
           for r in result.records[::2]]
    assert [entry for entry in bad if entry[1]] == []


def test_speed_exceedances_count_only_when_the_robot_does_not_react_and_brake():
    from shared.safety.monitor import MonitorResult, ReactionWindow, Violation

    def speeding(v):
        return MonitorResult(violations=[Violation("prbt_link_4", 0, "speed", 0.5, v, 0.1)])

    window = ReactionWindow(0.1, 0.3)
    assert window.update(0.00, speeding(0.6)) == []
    assert window.update(0.08, speeding(0.6)) == []             # reacting: may keep its speed for T_r
    assert window.update(0.25, speeding(0.25)) == []            # braking: under 0.6 (1 - 0.15 / 0.3) = 0.3
    assert len(window.update(0.26, speeding(0.5))) == 1         # not braking: above the envelope
    assert window.update(0.27, MonitorResult()) == []           # cleared ...
    assert window.update(0.28, speeding(0.6)) == []             # ... and the clock starts again
    slow = ReactionWindow(0.1, 0.3)
    assert slow.update(0.0, speeding(0.01)) == []
    assert slow.update(0.39, speeding(0.005)) == []             # within the envelope's tolerance
    assert len(slow.update(0.41, speeding(0.005))) == 1         # still approaching after T_r + T_s
    too_close = MonitorResult(violations=[Violation("prbt_link_4", 0, "separation", 0.01, 0.0, -1.0)])
    assert len(window.update(0.29, too_close)) == 1             # d_min at once


def test_a_lagging_monitor_pairs_each_joint_state_with_the_person_of_its_moment():
    from shared.safety.monitor import HumanHistory

    q = Q_START
    points, jac = ROBOT.capsule_kinematics(q)
    qd = np.array([-1.5, 0, 0, 0, 0, 0])
    heading = jac[-1, 0] @ qd
    flange = points[-1, 0]

    def person_at(distance):
        p = flange + distance * heading / np.linalg.norm(heading)
        return HumanCapsules.from_arrays([[p, p + [0, 0, 0.3]]], [0.05], np.zeros((1, 2, 3)), [True])

    near, far = person_at(0.25), person_at(3.0)
    history = HumanHistory(span=2.0)
    assert history.at(1.0) is None                               # nothing yet: nothing to check against
    history.add(10.0, far)
    history.add(10.5, near)                                      # the person came nearer at 10.5 s
    history.add(10.2, far)                                       # a late sample goes in its place
    # the joint state measured at 10.3 s, checked after 10.5 s: the person was still far then
    assert history.at(10.3) is far
    assert MONITOR.check(q, qd, history.at(10.3)).violations == []
    # ... while the one measured at 10.6 s is judged against the nearer person: exceedances are not hidden
    assert any(v.kind == "speed" for v in MONITOR.check(q, qd, history.at(10.6)).violations)
    assert history.at(9.0) is far                                # older than all: the oldest kept
    history.add(13.0, None)                                      # a lost track; older samples forgotten
    assert history.at(12.9) is near and history.at(13.1) is None
    history.add(15.5, far)
    assert history.at(12.9) is None                              # 10.5 s fell out of the 2 s span


def _random_person(rng, m):
    segs = rng.uniform(-0.8, 0.8, (m, 2, 3))
    segs[..., 2] += 0.6
    segs[0, 1] = segs[0, 0]                     # a sphere (a head): the closest-point code's degenerate case
    return HumanCapsules(segs, rng.uniform(0.04, 0.15, m), rng.uniform(-1.5, 1.5, (m, 2, 3)), rng.random(m) < 0.7)


def test_the_batched_check_is_the_coal_check():
    """check_batch (its own compiled closest points, many states at once) against check (coal, one state):
    the same separations, margins and violations, penetrating pairs, spheres and untracked velocities
    included."""
    rng = np.random.default_rng(11)
    # two different people of 10 capsules: states of different human states are checked in one batch
    people = [_random_person(rng, 10), _random_person(rng, 3), None, HumanCapsules.empty(), _random_person(rng, 10)]
    n = 120
    qs = rng.uniform(ROBOT.limits.lower, ROBOT.limits.upper, (n, 6))
    qds = rng.uniform(-1.57, 1.57, (n, 6))
    humans = [people[k % len(people)] for k in range(n)]
    batch = MONITOR.check_batch(qs, qds, humans)
    violations = 0
    for q, qd, h, b in zip(qs, qds, humans, batch):
        ref = MONITOR.check(q, qd, h)
        assert b.min_separation == pytest.approx(ref.min_separation, abs=1e-9)
        assert b.min_margin == pytest.approx(ref.min_margin, abs=1e-9)
        key = lambda v: (v.link, v.capsule, v.kind)                               # noqa: E731
        assert sorted(map(key, b.violations)) == sorted(map(key, ref.violations))
        violations += len(ref.violations)
    assert violations > 50                                   # the comparison covered violations too


def test_a_state_is_checked_against_the_person_of_its_moment_or_counted_unchecked():
    from shared.safety.monitor import Backlog, HumanHistory
    person = _random_person(np.random.default_rng(2), 2)
    history = HumanHistory()
    backlog = Backlog(pair_wait=0.1, pair_age=0.1, deadline=0.5)
    q, moving = np.zeros(6), np.full(6, 0.5)
    backlog.add(0.94, q, q)                  # at rest: passes whoever is there (nothing approaches)
    backlog.add(0.95, q, moving)             # before any human state: unknown person
    history.add(1.0, person)
    backlog.add(1.01, q, moving)             # newer than every human sample: waits for the next one
    ready, unchecked = backlog.take(1.02, history)
    assert [(s, h.count) for s, _, _, h in ready] == [(0.94, 0)]
    assert [(u.stamp, u.kind) for u in unchecked] == [(0.95, "before any human state")] and len(backlog) == 1
    history.add(1.02, None)                  # the next sample: the tracker lost the track
    ready, unchecked = backlog.take(1.03, history)
    assert [(s, h is person) for s, _, _, h in ready] == [(1.01, True)] and unchecked == []
    backlog.add(1.03, q, moving)             # paired with the invalid track: unchecked, not a pass
    ready, unchecked = backlog.take(1.2, history)
    assert ready == [] and [(u.stamp, u.kind) for u in unchecked] == [(1.03, "invalid track")]
    assert "no valid track" in unchecked[0].reason
    backlog.add(1.5, q, moving)              # the tracker silent since 1.02: its person is 0.48 s old
    backlog.add(0.2, q, moving)              # reached long after it was measured: skipped, not judged
    ready, unchecked = backlog.take(1.7, history)
    assert ready == [] and [(u.stamp, u.kind) for u in unchecked] == [(0.2, "late"), (1.5, "tracker silent")]
    assert "after it was measured" in unchecked[0].reason and "ms old" in unchecked[1].reason and len(backlog) == 0


def test_with_a_cameras_latency_a_state_waits_for_the_person_of_its_moment_that_long_longer():
    """People samples stamped with their capture reach the monitor their latency later: a state measured at 1.00
    s, with the person captured at 0.98 s and 1.03 s arriving 0.15 s after each, must not be paired at 1.11 s
    with the person captured at 0.90 s alone (the plain wait, 0.1 s, is over); with the latency noted it waits,
    and is paired with the people of its moment (0.98's, and 0.90's in force before) once the one captured after
    it has come."""
    from shared.safety.monitor import Backlog, HumanHistory
    rng = np.random.default_rng(3)
    early, moment, later = (_random_person(rng, 1) for _ in range(3))
    q, moving = np.zeros(6), np.full(6, 0.5)
    for noted in (False, True):
        history, backlog = HumanHistory(), Backlog(pair_wait=0.1, pair_age=0.1, deadline=0.5)
        history.add(0.90, early)
        if noted:
            for _ in range(3):
                backlog.note_delay(0.15)
            backlog.note_delay(float("nan"))                 # no figure: ignored
        backlog.add(1.00, q, moving)
        ready, _ = backlog.take(1.11, history)              # 0.98's person is not here yet (comes at 1.13)
        if not noted:
            assert [h is early for _, _, _, h in ready] == [True]       # paired with a person 0.1 s old
            continue
        assert ready == [] and backlog.delay == 0.15
        history.add(0.98, moment)                           # arrived at 1.13
        history.add(1.03, later)                            # arrived at 1.18: the pairing is final
        ready, unchecked = backlog.take(1.18, history)
        (_, _, _, people), = ready                           # the people in force since: 0.90's and 0.98's
        assert unchecked == [] and people.count == early.count + moment.count
        assert np.array_equal(people.segments[:moment.count], moment.segments)    # newest first, not 1.03's
    capped = Backlog()
    capped.note_delay(9.0)
    capped.note_delay(-1.0)
    assert capped.delay == 0.5                               # never past a stale sample's age


def test_an_episode_of_a_robot_that_creeps_must_end_within_its_own_stopping_time():
    """The reaction window brakes over the T_s of the episode's first state (``MonitorResult.stop``): a robot
    that exceeds at a crawl (T_s 0.05 s) is late after T_r + 0.05 s, where one at full speed has 0.3 s."""
    from shared.safety.monitor import MonitorResult, ReactionWindow, Violation

    def speeding(speed, stop):
        return MonitorResult(violations=[Violation("prbt_link_5", 0, "speed", 0.5, speed, 0.0)], stop=stop)

    for stop, late_at in ((0.05, 0.16), (0.30, 0.41)):
        window = ReactionWindow(0.1, 0.3)
        assert window.update(0.0, speeding(0.05, stop)) == []
        assert window.update(late_at - 0.02, speeding(0.001, stop)) == []
        assert len(window.update(late_at, speeding(0.001, stop))) == 1, stop
    state = MONITOR.check(Q_START, np.array([0.0, 0.785, 0, 0, 0, 0]), HumanCapsules.empty())
    assert np.isnan(state.stop)                                       # nobody: nothing checked
    near = HumanCapsules.from_arrays([[[0.5, 0, 1.0], [0.5, 0, 1.4]]], [0.1], np.zeros((1, 2, 3)), [True])
    one = MONITOR.check(Q_START, np.array([0.0, 0.785, 0, 0, 0, 0]), near)
    batch = MONITOR.check_batch(Q_START[None], np.array([[0.0, 0.785, 0, 0, 0, 0]]), [near])[0]
    assert one.stop == pytest.approx(0.15) and batch.stop == pytest.approx(0.15)
