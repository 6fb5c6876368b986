"""Real people through the cores: the human-assembly recordings (arm-only camera skeletons at 30 Hz), the
tracker at a camera's rate, short person states counted by the monitor, and no speed-up towards a person
whose velocity is unknown."""


import dataclasses
import json

import numpy as np
import pytest

from shared.core.errors import ConfigError
from shared.core.humans import HumanCapsules
from shared.safety.monitor import Backlog, HumanHistory
from shared.tracking.keypoints import FrameTransform, convert, read_assembly, to_motion
from shared.tracking.motion import RecordedMotion
from shared.tracking.tracker import HumanTracker, TrackerParameters, stale_bound
from tests.util import ROOT

DATA = ROOT / "tests" / "data" / "human-assembly" / "task1_human1_trial1_first300.txt"
PLACEMENT = FrameTransform(translation=(-0.05, 0.0, 1.1), camera=True)


def test_a_recording_becomes_seven_capsules_a_frame_in_front_of_the_robot(tmp_path):
    out = tmp_path / "motion.json"
    frames, dropouts = convert(DATA, out, PLACEMENT, "assembly", 30.0)
    assert (frames, dropouts) == (300, 0)
    motion = RecordedMotion.load(out)
    assert motion.rate == pytest.approx(30.0) and motion.duration == pytest.approx(299 / 30)
    caps = motion.at(1.0)
    assert caps.count == 7
    assert set(motion.frames[30].names) == {"torso", "l_upper_arm", "l_forearm", "l_hand", "r_upper_arm",
                                           "r_forearm", "r_hand"}
    # the person faces the robot (+x) from -x, hands in front of the shoulders, torso vertical
    torso, l_hand = caps.segments[0], caps.segments[3]
    assert torso[0, 2] < torso[1, 2] and np.allclose(torso[0, :2], torso[1, :2])
    assert -1.1 < torso[0, 0] < -0.7 and l_hand[0, 0] > torso[0, 0] and l_hand[0, 1] > 0   # left is +y


def test_every_other_frame_is_the_same_person_as_a_15_hz_camera_sees_them(tmp_path):
    """--every 2: the first frame and every second after it, each at its own time, so the motion runs as long and
    its rate is halved; the tracker then measures 15 Hz and stretches its window to it, and its dropout bound to
    the ceiling (100 ms: 1.5 intervals, not 2.5; a slower source is stale sooner, T_r covering its age)."""
    full, half = tmp_path / "full.json", tmp_path / "half.json"
    convert(DATA, full, PLACEMENT, "assembly", 30.0)
    assert convert(DATA, half, PLACEMENT, "assembly", 30.0, every=2) == (150, 0)
    a, b = RecordedMotion.load(full), RecordedMotion.load(half)
    assert b.rate == pytest.approx(15.0) and b.frames[1].t == pytest.approx(2 / 30)
    assert np.allclose(b.frames[7].segments, a.frames[14].segments)
    tracker = HumanTracker()
    for frame in b.frames[:6]:
        out = tracker.update(frame.segments, frame.radii, frame.t, frame.t)
    assert tracker.interval == pytest.approx(1 / 15) and tracker.dropout == stale_bound(0.05, 1 / 15) == 0.1
    assert out.velocity_known.all()                  # four frames within 3.5 intervals: known from the fourth
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ConfigError, match="every: expected a whole number >= 1"):
            convert(DATA, half, PLACEMENT, "assembly", 30.0, every=bad)


def test_a_keypoint_openpose_missed_makes_a_dropout_frame_and_a_broken_row_names_its_line():
    rows = DATA.read_text().splitlines()[:3]
    cells = rows[1].split()
    cells[0] = "nan"
    frames = read_assembly("\n".join([rows[0], " ".join(cells), rows[2]]), "rec")
    doc, dropouts = to_motion(frames, PLACEMENT)
    assert dropouts == 1 and doc["frames"][1]["dropout"] and "l_hand" in doc["frames"][1]["label"]
    with pytest.raises(ConfigError, match="rec: line 2: expected 18 numbers"):
        read_assembly("\n".join([rows[0], " ".join(rows[1].split()[:17])]), "rec")      # truncated
    with pytest.raises(ConfigError, match="line 1: 'x1' is not a number"):
        read_assembly(" ".join(["x1"] + rows[0].split()[1:]), "rec")
    with pytest.raises(ConfigError, match="no frames"):
        read_assembly("\n\n", "rec")
    with pytest.raises(ConfigError, match="frame rate"):
        read_assembly(rows[0], "rec", rate=float("nan"))


def test_the_tracker_measures_a_camera_rate_and_scales_its_window_and_dropout():
    """A 30 Hz skeleton: 40 ms never holds four samples; the window stretches to 3.5 intervals, so the velocity
    is known after four frames, and the dropout bound is 2.5 intervals (one lost frame is no lost person), not 50 ms."""
    tracker = HumanTracker()
    seg = np.array([[[0.0, 0.0, 1.0], [0.0, 0.0, 1.5]]])
    known = []
    for k in range(8):
        t = k / 30.0
        out = tracker.update(seg + np.array([0.5 * t, 0.0, 0.0]), np.array([0.1]), t, t)
        known.append(bool(out.velocity_known.all()))
    assert known == [False, False, False, True, True, True, True, True]
    assert tracker.interval == pytest.approx(1 / 30)
    assert out.velocities[0, 0, 0] == pytest.approx(0.5)
    assert tracker.dropout == pytest.approx(2.5 / 30) == stale_bound(0.05, 1 / 30)
    assert tracker.valid(7 / 30 + 0.08) and not tracker.valid(7 / 30 + 0.09)
    assert stale_bound(0.05, 1.0) == 0.1 and stale_bound(0.3, 1.0) == 0.3     # a slow source: not by its rate
    fast = HumanTracker()                                    # 240 Hz motion capture keeps the 50 ms and 40 ms
    for k in range(20):
        fast.update(seg, np.array([0.1]), k / 240, k / 240)
    assert fast.dropout == 0.05 and fast.window == 0.04


def test_a_declared_camera_rate_holds_the_track_between_its_first_two_frames():
    """A 15 Hz camera's second frame comes 67 ms after its first. Before any interval is measured a source gets
    the configured 50 ms: its track is lost at 50 ms with the person in view. With the rate declared
    (source_interval) the first frame's bound is the 15 Hz one (100 ms), the state's interval says so (the
    scaler's stale bound follows it), and from the second frame the measured interval replaces the declared."""
    seg = np.array([[[0.0, 0.0, 1.0], [0.0, 0.0, 1.5]]])
    unknown, declared = HumanTracker(), HumanTracker(TrackerParameters(source_interval=1 / 15))
    for tracker in (unknown, declared):
        tracker.update(seg, np.array([0.1]), 0.0, 0.0)
    assert not unknown.valid(0.067) and unknown.interval == 0.0
    assert declared.valid(0.067) and declared.dropout == stale_bound(0.05, 1 / 15) == 0.1
    assert not declared.valid(0.101)                           # a silent camera is still lost, at its own bound
    declared.update(seg, np.array([0.1]), 0.05, 0.05)          # it runs at 20 Hz: measured, not declared
    assert declared.interval == pytest.approx(0.05)
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="source_interval"):
            TrackerParameters(source_interval=bad)


def test_a_person_state_shorter_than_a_joint_period_is_checked_too():
    """Joint states at 0.00 and 0.01 s; between them a 4 ms state with the velocity unknown. The monitor's
    pairing holds the joint state at 0.01 against both states of its period."""
    history = HumanHistory()
    seg = np.array([[[1.0, 0.0, 0.5], [1.0, 0.0, 1.5]]])
    known = HumanCapsules(seg, np.array([0.1]), np.zeros((1, 2, 3)), np.array([True]))
    unknown = HumanCapsules(seg, np.array([0.1]), np.zeros((1, 2, 3)), np.array([False]))
    history.add(-0.001, known)
    history.add(0.004, unknown)
    history.add(0.008, known)
    stamp, merged = history.pair_since(0.01, 0.0)
    assert stamp == 0.008 and merged.count == 3 and not merged.velocity_known.all()
    assert history.pair(0.01)[1] is known                     # the newest alone would have missed it
    backlog = Backlog()
    backlog.add(0.0, np.zeros(6), np.ones(6))
    backlog.add(0.01, np.zeros(6), np.ones(6))
    history.add(0.02, known)
    ready, unchecked = backlog.take(0.03, history)
    assert unchecked == [] and [r[3].count for r in ready] == [1, 3]


def test_the_union_of_states_keeps_every_capsule_newest_first():
    a = HumanCapsules.from_arrays(np.zeros((1, 2, 3)), [0.1])
    b = HumanCapsules.from_arrays(np.ones((2, 2, 3)), [0.2, 0.3], np.zeros((2, 2, 3)))
    u = HumanCapsules.union([b, a])
    assert u.count == 3 and u.radii.tolist() == [0.2, 0.3, 0.1] and u.velocity_known.tolist() == [True, True, False]
    assert HumanCapsules.union([a]) is a and HumanCapsules.union([]).count == 0


def test_a_capsule_of_unknown_velocity_within_reach_holds_the_path_speed():
    """unknown_within_reach: true only where a capsule of unknown velocity would be approached faster than
    its limit at full path speed (the scaling layer then keeps alpha at most the last cycle's, '+unknown')."""
    from shared.safety.ssm import PairSsm
    from shared.scaling.layer import unknown_within_reach

    pairs = PairSsm(np.ones((2, 2)), np.array([[0.5, 0.5], [0.1, 0.1]]), np.zeros((2, 2)),
                    np.array([[0.3, 1.0], [0.3, 1.0]]))
    assert unknown_within_reach(pairs, np.array([False, True]))          # 0.5 m/s against a 0.3 m/s limit
    assert not unknown_within_reach(pairs, np.array([True, False]))      # the unknown one is within its limit
    assert not unknown_within_reach(pairs, np.array([True, True]))


def test_the_scaler_checks_every_human_state_since_its_last_tick():
    from services.scaler import merge_human_states
    from shared.wire.convert import humans_to_msg

    a = HumanCapsules.from_arrays(np.zeros((1, 2, 3)), [0.1], np.zeros((1, 2, 3)))
    b = HumanCapsules.from_arrays(np.ones((1, 2, 3)), [0.2])
    merged = merge_human_states([humans_to_msg(a, True, 0.0), humans_to_msg(b, True, 0.004),
                                 humans_to_msg(a, True, 0.008)])
    assert merged.count == 3 and merged.velocity_known.tolist() == [True, False, True]
    assert merge_human_states([humans_to_msg(a, True, 0.0), humans_to_msg(HumanCapsules.empty(), False, 0.01)]) is None


def test_the_independent_recount_counts_a_robot_that_does_not_brake_and_agrees_with_the_monitor_rule():
    """A link driving at 0.5 m/s straight at a person inside their no-approach distance for 0.5 s: T_r to
    react, then the braking line; not braking is counted from T_r on, by the judge and by the monitor."""
    from shared.config import CellConfig
    from shared.robot.model import default_robot
    from shared.safety.monitor import ReactionWindow, SafetyMonitor
    from shared.wire.convert import humans_to_msg
    from shared.wire.messages import JointState
    from tools.judge import recount

    robot, config = default_robot(), CellConfig()
    q = np.array([0.0, -0.4, 1.17, 0.0, 1.57, 0.0])
    qd = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    qd[0] = 1.0                                                # turning about the base
    ends = robot.capsule_segments(q)[-1]
    target = ends[0] + np.array([0.0, 0.45, 0.0])              # beside the flange, where it turns to
    person = HumanCapsules(np.array([[target, target + [0, 0, 0.3]]]), np.array([0.1]), np.zeros((1, 2, 3)),
                           np.array([True]))
    joints = [JointState(q=q, qd=qd, enabled=True, fault=False, drive_state="operation_enabled", stamp=0.01 * k)
              for k in range(50)]
    people = [humans_to_msg(person, True, 0.01 * k - 0.002) for k in range(50)]
    judged = recount(robot, config, joints, people)
    monitor, history = SafetyMonitor(robot, config.ssm), HumanHistory()
    window = ReactionWindow(config.ssm.reaction_time, config.ssm.stopping_time)
    for msg in people:
        history.add(msg.sample_stamp, person)
    before = [-np.inf] + [js.stamp for js in joints[:-1]]
    results = monitor.check_batch(np.array([js.q for js in joints]), np.array([js.qd for js in joints]),
                                  [history.pair_since(js.stamp, after)[1] for js, after in zip(joints, before)])
    counted = sum(len(window.update(js.stamp, r)) for js, r in zip(joints, results))
    assert judged.exceedances > 0 and judged.violations == counted > 0
    assert judged.unchecked == 0 and judged.states == 50


def test_the_independent_recount_says_which_speed_ups_went_towards_a_velocity_it_did_not_know():
    """The link of the test above speeding up within T_r of its first exceedance (1.0 to 1.4 rad/s about the
    base): speed-ups, each at its joint state's stamp; towards the person whose velocity the tracker did not know,
    all of them are counted as such, towards the same person with a known velocity none; and with the commands,
    those a command made (the cell, knowing the velocity unknown, sped up), not the drives' lag."""
    from shared.config import CellConfig
    from shared.robot.model import default_robot
    from shared.wire.convert import humans_to_msg
    from shared.wire.messages import JointCommand, JointState
    from tools.judge import recount

    robot, config = default_robot(), CellConfig()
    q = np.array([0.0, -0.4, 1.17, 0.0, 1.57, 0.0])
    target = robot.capsule_segments(q)[-1][0] + np.array([0.0, 0.45, 0.0])
    joints = [JointState(q=q, qd=np.array([1.0 + 0.1 * min(k, 4), 0, 0, 0, 0, 0]), enabled=True, fault=False,
                         drive_state="operation_enabled", stamp=0.01 * k) for k in range(10)]
    for known in (False, True):
        person = HumanCapsules(np.array([[target, target + [0, 0, 0.3]]]), np.array([0.1]), np.zeros((1, 2, 3)),
                               np.array([known]))
        people = [humans_to_msg(person, True, 0.01 * k - 0.002) for k in range(10)]
        judged = recount(robot, config, joints, people, tolerance=1e-3)    # link 1's approach: 14 to 20 mm/s
        assert judged.speedups > 0 and judged.speedups_unknown == (0 if known else judged.speedups)
        assert len(judged.speedup_stamps) == min(judged.speedups, 10)
        # within T_r of their episode's start: the person's states in force at a joint state are paired each (the
        # newest and the one before it), the second pair's episode a state later
        assert judged.speedup_stamps[0] == pytest.approx(0.01)
        assert max(judged.speedup_stamps) <= config.ssm.reaction_time + 0.01 + 1e-9
        assert judged.speedups_unknown_commanded is None                      # no commands: unchecked, not 0
        # with the scaler's commands, each computed from the newest person state 1 ms before its joint state: the
        # commands slowing (the joints a period behind them, still speeding up: the drives' lag) made none of them;
        # the commands speeding up made every one towards the unknown velocity
        for step, made in ((-0.05, 0), (0.1, judged.speedups_unknown)):
            commands = [JointCommand(q=q, qd=np.array([1.4 + step * k, 0, 0, 0, 0, 0]), trajectory_version=1, s=0.0,
                                     human_sample_stamp=0.01 * k - 0.002, human_wait=0.0, stamp=0.01 * k - 0.001)
                        for k in range(10)]
            with_commands = recount(robot, config, joints, people, tolerance=1e-3, commands=commands)
            assert with_commands.speedups_unknown == judged.speedups_unknown
            assert with_commands.speedups_unknown_commanded == made
            # plain numbers, as the report writes them to JSON (numpy's once lost a run's summary.json)
            assert type(with_commands.speedups_unknown_commanded) is int
            json.dumps(dataclasses.asdict(with_commands))


def test_in_the_loop_the_robot_holds_its_speed_while_a_velocity_near_it_is_unknown():
    """The shuttle slowed to below half its path speed by a person 0.9 m off along x, 0.7 m to its side; the
    person steps back to 1.5 m with the velocity unknown (a glitch): the SSM alone would let the robot speed up
    again (its bound is above the path speed), but it holds its speed; once the velocity is known it speeds up."""
    from evidence.scenarios import Q_GOAL, Q_START
    from shared.core.trajectory import straight_line_trajectory
    from shared.robot.model import default_robot
    from shared.safety.parameters import SsmParameters
    from shared.scaling.layer import ScalingInputs, ScalingLayer

    robot = default_robot()

    def person(x, known):
        return HumanCapsules(np.array([[[x, -0.7, 0.4], [x, -0.7, 1.5]]]), np.array([0.2]), np.zeros((1, 2, 3)),
                             np.array([known]))

    lay = ScalingLayer(robot, SsmParameters())
    lay.set_trajectory(straight_line_trajectory(Q_START, Q_GOAL, robot.limits.velocity, robot.limits.acceleration))
    for _ in range(40):
        lay.step(ScalingInputs(humans=person(-3.0, True)))
    for _ in range(15):
        step = lay.step(ScalingInputs(humans=person(-0.9, True)))
    held = step.sdot
    assert 0.1 < held < 0.5
    for _ in range(5):
        step = lay.step(ScalingInputs(humans=person(-1.5, False)))
        assert step.sdot == held and step.safe_alpha > held and step.method.endswith("+unknown")
    assert lay.step(ScalingInputs(humans=person(-1.5, True))).sdot > held


def test_on_a_start_ramp_the_joints_speed_is_held_not_only_alpha_while_a_velocity_near_it_is_unknown():
    """The shuttle leaving from rest beside a person (0.9 m off along x, 0.5 m to its side); three periods into its
    start ramp the person's velocity turns unknown: q'(s) still rises along the ramp, so a held alpha (the rule's
    first form) let the joints speed up from 0.63 to 0.80 rad/s in five periods; the commanded joint speed is held
    now, and rises again once the velocity is known."""
    from evidence.scenarios import Q_GOAL, Q_START
    from shared.core.trajectory import straight_line_trajectory
    from shared.robot.model import default_robot
    from shared.safety.parameters import SsmParameters
    from shared.scaling.layer import ScalingInputs, ScalingLayer

    robot = default_robot()
    person = [HumanCapsules(np.array([[[-0.9, 0.5, 0.4], [-0.9, 0.5, 1.5]]]), np.array([0.2]), np.zeros((1, 2, 3)),
                            np.array([known])) for known in (False, True)]
    lay = ScalingLayer(robot, SsmParameters())
    lay.set_trajectory(straight_line_trajectory(Q_START, Q_GOAL, robot.limits.velocity, robot.limits.acceleration))
    speeds = [float(np.abs(lay.step(ScalingInputs(humans=person[True])).qd_command).max()) for _ in range(3)]
    assert speeds[0] < speeds[1] < speeds[2]                   # known: it speeds up along the ramp
    for _ in range(30):
        step = lay.step(ScalingInputs(humans=person[False]))
        speeds.append(float(np.abs(step.qd_command).max()))
        assert step.method.endswith("+unknown") and speeds[-1] <= speeds[-2] + 1e-12
        assert step.safe_alpha > step.alpha                     # the SSM alone would let it speed up
    assert float(np.abs(lay.step(ScalingInputs(humans=person[True])).qd_command).max()) > speeds[-1]
