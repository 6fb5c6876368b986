"""The SSM-aware time cost (shared.planning.time_cost) and the search that minimises it (shared.planning.path_search)."""

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START, body_segments
from shared.core.humans import HumanCapsules
from shared.core.trajectory import polyline_trajectory, straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.forecast import ConstantVelocity, PeopleForecast
from shared.planning.path_search import PathSearch, SearchOptions
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.planning.time_cost import SsmTimeCost, TimeCostOptions
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.scaling.problem import ssm_alpha_bound
from tests.util import LAID_OUT_SSM

ROBOT = default_robot()
LIM = ROBOT.limits
# The paper's formula (the measured human speed held): these tests hold the layers' logic on the paper's
# numbers; the shipped human model's own figures are tests/safety/test_ssm.py's and the cell's.
SSM = SsmParameters().paper_formula()
COST = SsmTimeCost(ROBOT, SSM)
CM = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE))
OLD = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration)


def person(x: float, y: float, reach: float, target, velocity=(0.0, 0.0, 0.0)) -> HumanCapsules:
    seg, radii = body_segments(x, y, reach, np.asarray(target, dtype=float))
    vel = np.broadcast_to(np.asarray(velocity, dtype=float), seg.shape).copy()
    return HumanCapsules.from_arrays(seg, radii, vel, np.ones(len(radii), bool))


NEAR = person(-1.0, 0.0, 1.0, (-0.4, 0.0, 0.8))          # reaching over the shuttle's middle
WALKING = person(-1.6, 0.0, 0.0, (-0.4, 0.0, 0.8), velocity=(0.8, 0.0, 0.0))


def reference_time(traj, humans, options=TimeCostOptions()) -> float:
    """The definition, written out sample by sample with the scaling layer's own bound: a sample slower
    than wait_step is waited at in steps of wait_step, each with the people moved on by then (along their
    velocities, every part: these people walk faster than the standing speed)."""
    s = np.arange(0.0, traj.duration, options.trajectory_step)
    q, dq, _ = traj.sample(s)
    dt = np.diff(np.append(s, traj.duration))
    total = 0.0
    for qk, dqk, dtk in zip(q, dq, dt):
        left = 1.0
        while left > 0.0:
            shift = min(total, options.extrapolation)
            moved = HumanCapsules(humans.segments + shift * humans.velocities, humans.radii, humans.velocities,
                                  humans.velocity_known)
            alpha = max(ssm_alpha_bound(ROBOT, qk, dqk, moved, SSM), options.alpha_floor)
            need = left * dtk / alpha
            step = min(need, options.wait_step) if shift < options.extrapolation else need
            total += step
            left = 0.0 if step >= need else left - step * alpha / dtk
    return total


def test_the_compiled_cost_is_the_scaling_layers_bound_sample_by_sample():
    for humans in (NEAR, WALKING):
        assert COST.trajectory_time(OLD, 0.0, humans) == pytest.approx(reference_time(OLD, humans), rel=1e-9)
    # nobody near, or nobody at all: the nominal time
    assert COST.trajectory_time(OLD, 0.0, None) == pytest.approx(OLD.duration)
    far = person(-2.8, 0.0, 0.0, (0, 0, 0.5))
    assert COST.trajectory_time(OLD, 0.0, far) == pytest.approx(OLD.duration)


def test_a_person_walking_out_of_the_way_is_waited_for_only_until_they_have_gone():
    # reaching over the shuttle and walking off sideways: the robot's first samples are at the alpha floor
    # now, but clear a moment later; a prediction charging those samples at the people's position of now
    # (wait_step inf) waits 50 times their nominal time, as if the person stood still
    walking_off = person(-1.0, 0.0, 1.0, (-0.4, 0.0, 0.8), velocity=(0.0, -1.5, 0.0))
    stepped = COST.trajectory_time(OLD, 0.0, walking_off)
    lump = SsmTimeCost(ROBOT, SSM, TimeCostOptions(wait_step=np.inf)).trajectory_time(OLD, 0.0, walking_off)
    assert stepped == pytest.approx(reference_time(OLD, walking_off), rel=1e-9)
    assert OLD.duration < stepped < OLD.duration + 0.3 and lump > stepped + 2.0


def test_a_straight_path_costs_its_trapezoid_and_bends_cost_time():
    assert COST.path_time(np.vstack([Q_START, Q_GOAL]), None) == pytest.approx(OLD.duration, rel=1e-9)
    via = (Q_START + Q_GOAL) / 2 + np.array([0.0, 0.5, -0.5, 0.0, 0.0, 0.0])
    bent = np.vstack([Q_START, via, Q_GOAL])
    assert COST.path_time(bent, None) > OLD.duration
    # the bent path's real time law (stopping at the corner) is no faster than its estimate says
    assert polyline_trajectory(bent, LIM.velocity, LIM.acceleration).duration >= COST.path_time(bent, None) - 1e-9


def test_path_samples_walk_each_segment_from_its_start_with_the_rests_and_corners_on_the_timeline():
    """The time a time law adds (the start from rest, a corner, the stop) is a sample at rest where it happens,
    not a lump at the end: every later sample is predicted when the robot gets there."""
    a = np.zeros(6)
    b = a + np.array([0.12, 0.0, 0.0, 0.0, 0.0, 0.0])                # 0.12 rad: 3 samples at 0.05 rad spacing
    c = b + np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])                 # a corner, then 6 samples
    samples = COST.path_samples(np.vstack([a, b, b, c]))           # the repeated waypoint is no segment
    # at rest at a, 3 moving, the corner at b, 6 moving, the stop at c
    assert samples.q.shape == (12, 6) and np.allclose(samples.q[[0, 1, 4, 5, 11]], [a, a, b, b, c])
    assert not samples.dq[[0, 4, 11]].any() and samples.overhead == 0.0
    assert np.allclose(samples.q[1:4, 0], [0.0, 0.04, 0.08])         # from the start, evenly
    v0, v1 = 0.12 / COST.segment_time(a, b), 0.3 / COST.segment_time(b, c)
    assert np.allclose(samples.dq[1:4, 0], v0) and np.allclose(samples.dq[5:11, 1], v1)
    acc = LIM.acceleration
    start, corner, stop = v0 / (2 * acc[0]), max(v0 / (2 * acc[0]), v1 / (2 * acc[1])), v1 / (2 * acc[1])
    assert samples.dt[[0, 4, 11]] == pytest.approx([start, corner, stop])
    assert samples.nominal == pytest.approx(COST.segment_time(a, b) + COST.segment_time(b, c) + start + corner + stop)
    # moving already at the start: no start-up; nothing to walk: nothing
    moving = COST.path_samples(np.vstack([a, b, c]), from_rest=False)
    assert moving.q.shape == (11, 6) and moving.dq[0].any()
    assert moving.nominal == pytest.approx(samples.nominal - start)
    empty = COST.path_samples(np.vstack([a, a]))
    assert empty.q.shape == (0, 6) and empty.nominal == 0.0


def test_the_predicted_timeline_of_a_straight_leg_is_the_time_law_s_once_it_is_at_speed():
    """A straight leg from rest, nobody near enough to slow it: the time the cost predicts the robot at each
    sample after its start-up ramp is when the trapezoid gets there, within one control period (the ramp itself
    is one sample at rest: within it the prediction is at most v / 2a early or late)."""
    far = person(-6.0, 0.0, 0.0, (-5.6, 0.0, 0.8))
    samples = COST.path_samples(np.vstack([Q_START, Q_GOAL]))
    ends = COST._walk(samples, far, np.inf, True)
    start_of = np.concatenate([[0.0], ends[:-1]])                  # when each sample is predicted to begin
    law = OLD
    t = np.linspace(0.0, law.duration, 20001)
    along = np.abs(law.sample(t)[0][:, 0] - Q_START[0])            # joint 1 leads the synchronised motion
    ramp = float(np.max(LIM.velocity[0] / LIM.acceleration[0]))   # s: the start-up ramp of the leading joint
    for k in range(1, samples.q.shape[0] - 1):
        reached = float(t[np.searchsorted(along, abs(samples.q[k, 0] - Q_START[0]) - 1e-9)])
        if reached >= ramp and reached <= law.duration - ramp:
            assert start_of[k] == pytest.approx(reached, abs=0.01), k
    assert ends[-1] == pytest.approx(law.duration, abs=0.01)


def test_people_stay_for_the_stay_and_move_on_along_their_velocities():
    # a person who leaves at once costs nothing; the longer they stay, the longer the way past them
    times = [COST.trajectory_time(OLD, 0.0, NEAR, stay) for stay in (0.0, 0.5, 2.0, np.inf)]
    assert times[0] == pytest.approx(OLD.duration)
    assert times == sorted(times) and times[-1] > times[0] + 1.0
    # walking up to the path: slower than where they stand now predicts, because they get closer
    assert COST.trajectory_time(OLD, 0.0, WALKING) > COST.stretched(COST.trajectory_samples(OLD, 0.0), WALKING,
                                                                    moving=False)


def test_a_person_shifting_their_stance_is_predicted_where_they_stand():
    """A body slower than STANDING_SPEED (0.12 m/s towards the path here) is not moved on along its velocity:
    a person shifting their stance or leaning in does not walk anywhere (one predicted 0.25 m further in made a
    goal planned while they stepped in go straight into their slowdown). With a lower drift speed they are."""
    shifting = person(-1.2, 0.0, 1.0, (-0.4, 0.0, 0.8), velocity=(0.12, 0.0, 0.0))
    where_they_are = COST.stretched(COST.trajectory_samples(OLD, 0.0), shifting, moving=False)
    assert COST.trajectory_time(OLD, 0.0, shifting) == pytest.approx(where_they_are)
    drifting = SsmTimeCost(ROBOT, SSM, TimeCostOptions(drift_speed=0.1))
    assert drifting.trajectory_time(OLD, 0.0, shifting) > where_they_are + 0.05


def test_the_default_forecast_is_constant_velocity_and_holds_a_shifting_stance():
    # two frames, the second `horizon` on along the velocity: linear in between is constant velocity exactly
    ahead = ConstantVelocity().forecast(WALKING, 2.0)
    assert ahead.frames.shape == (2, WALKING.count, 2, 3) and ahead.horizon == pytest.approx(2.0)
    np.testing.assert_allclose(ahead.frames[1], WALKING.segments + 2.0 * WALKING.velocities)
    shifting = person(-1.2, 0.0, 1.0, (-0.4, 0.0, 0.8), velocity=(0.12, 0.0, 0.0))
    np.testing.assert_array_equal(ConstantVelocity().forecast(shifting, 2.0).frames[1], shifting.segments)
    unknown = HumanCapsules.from_arrays(WALKING.segments, WALKING.radii)     # no tracked velocity: stays
    np.testing.assert_array_equal(ConstantVelocity().forecast(unknown, 2.0).frames[-1], unknown.segments)
    assert ConstantVelocity().forecast(WALKING, 0.0).horizon == 0.0


class Frames:
    """A forecaster of hand-made frames (times 0, step, ...): what a better prediction would plug in."""

    def __init__(self, frames, step: float, velocities=None) -> None:
        self.frames, self.step, self.calls = np.asarray(frames), step, 0
        self.velocities = np.broadcast_to(0.0 if velocities is None else velocities, self.frames.shape)

    def forecast(self, humans, horizon):
        self.calls += 1
        return PeopleForecast(self.frames, self.velocities, self.step)


def test_a_forecast_of_many_frames_is_interpolated_between_them():
    """Twenty-one frames of the walking person's constant-velocity motion give the two-frame forecast's time;
    the same person forecast to turn back at once is out of the way sooner."""
    times = np.arange(21) * 0.1
    walk = WALKING.segments[None] + times[:, None, None, None] * WALKING.velocities[None]
    cost = SsmTimeCost(ROBOT, SSM, forecaster=Frames(walk, 0.1, WALKING.velocities))
    assert cost.trajectory_time(OLD, 0.0, WALKING) == pytest.approx(COST.trajectory_time(OLD, 0.0, WALKING), rel=1e-9)
    back = WALKING.segments[None] - times[:, None, None, None] * WALKING.velocities[None]
    turning = SsmTimeCost(ROBOT, SSM, forecaster=Frames(back, 0.1, -WALKING.velocities))
    assert turning.trajectory_time(OLD, 0.0, WALKING) < COST.trajectory_time(OLD, 0.0, WALKING) - 0.05


def test_people_the_forecast_does_not_move_are_waited_out_at_once_with_the_prediction_of_looking_again():
    """A forecast in which nobody moves (every frame the first one's: people standing) would show the same people
    at every look again, so a slow sample is waited out in one step (session 85: the search's costing 2-3x faster
    beside standing people); it predicts what looking again every wait_step predicts, a forecast moved by a
    picometre (which looks again) the same to 1e-9; a stay that ends mid-wait ends it there too."""
    held = np.stack([NEAR.segments] * 3)
    nudged = held.copy()
    nudged[-1] += 1e-12
    for stay in (np.inf, 2.0, 6.0):
        still = SsmTimeCost(ROBOT, SSM, forecaster=Frames(held, 1.0)).trajectory_time(OLD, 0.0, NEAR, stay)
        looked = SsmTimeCost(ROBOT, SSM, forecaster=Frames(nudged, 1.0)).trajectory_time(OLD, 0.0, NEAR, stay)
        assert still == pytest.approx(looked, rel=1e-9) and still > OLD.duration + 0.5, stay


def test_one_forecast_serves_a_search_and_a_wrong_one_is_refused():
    frames = Frames(NEAR.segments[None], 1.0)
    cost = SsmTimeCost(ROBOT, SSM, forecaster=frames)
    for _ in range(3):                               # the same tracked people: forecast once
        cost.trajectory_time(OLD, 0.0, NEAR)
    assert frames.calls == 1
    cost.trajectory_time(OLD, 0.0, person(-1.0, 0.0, 1.0, (-0.4, 0.0, 0.8)))   # a new snapshot: forecast anew
    assert frames.calls == 2
    # a forecast of other people than those tracked is an error, not a silent mismatch
    with pytest.raises(ValueError, match="capsules"):
        SsmTimeCost(ROBOT, SSM, forecaster=Frames(NEAR.segments[None, :1], 1.0)).trajectory_time(OLD, 0.0, NEAR)
    with pytest.raises(ValueError, match="step"):
        PeopleForecast(NEAR.segments[None], NEAR.velocities[None], 0.0)
    with pytest.raises(ValueError, match="shape"):
        PeopleForecast(NEAR.segments[None], NEAR.velocities, 1.0)


def test_people_who_may_walk_on_or_stop_cost_the_expected_time_over_both():
    """WalksOrStops: the time cost is the weighted mean of the time with the person walking on (the default
    forecast) and with them stopped where they are; weight 1 is the default forecast's time exactly; bad
    weights are refused."""
    from shared.planning.forecast import WalksOrStops

    class Still:
        def forecast(self, humans, horizon):
            return PeopleForecast.still(humans)

    walking = COST.trajectory_time(OLD, 0.0, WALKING)
    stopped = SsmTimeCost(ROBOT, SSM, forecaster=Still()).trajectory_time(OLD, 0.0, WALKING)
    assert abs(walking - stopped) > 0.05                   # the two hypotheses differ here
    for weight in (0.0, 0.3, 1.0):
        cost = SsmTimeCost(ROBOT, SSM, forecaster=WalksOrStops(weight))
        assert cost.trajectory_time(OLD, 0.0, WALKING) == pytest.approx(weight * walking + (1 - weight) * stopped,
                                                                         rel=1e-9)
    with pytest.raises(ValueError, match="walk_weight"):
        WalksOrStops(1.5)

    class Unweighted(WalksOrStops):
        def hypotheses(self, humans, horizon):
            return [(0.7, self.forecast(humans, horizon)), (0.7, PeopleForecast.still(humans))]

    with pytest.raises(ValueError, match="summing to 1"):
        SsmTimeCost(ROBOT, SSM, forecaster=Unweighted()).trajectory_time(OLD, 0.0, WALKING)


def test_reached_is_where_the_bound_lets_a_crawling_robot_get_in_that_time():
    # nobody near: full speed, never past the end
    assert COST.reached(OLD, 0.5, None, 0.3) == pytest.approx(0.8)
    assert COST.reached(OLD, OLD.duration - 0.1, None, 0.3) == pytest.approx(OLD.duration)
    for s0 in (0.5, 0.7, 0.8):                   # towards the person reaching over the path: slowing down
        got = COST.reached(OLD, s0, NEAR, 0.3)
        s, t = s0, 0.0                           # the reference: the scaling layer's bound, 0.1 ms steps
        while t < 0.3 - 1e-12:
            q, dq, _ = OLD.sample(np.array([s]))
            s, t = s + max(ssm_alpha_bound(ROBOT, q[0], dq[0], NEAR, SSM), 0.02) * 1e-4, t + 1e-4
        q, dq, _ = OLD.sample(np.array([s0]))
        at_present_rate = s0 + 0.3 * ssm_alpha_bound(ROBOT, q[0], dq[0], NEAR, SSM)
        # within 5 % of the way made (each step takes the bound at its start: a little ahead; 12 % with
        # the first walk's steps alone, which span the whole 0.3 s of nominal time)
        assert s - 1e-9 <= got <= s + 0.05 * (s - s0), (s0, got, s)
        assert got < at_present_rate - 0.005, (s0, got, at_present_rate)
    # a person who stays where the bound is zero: the robot does not get on while they stay (within the
    # interpolation across the step it waits in: its 0.015 s of nominal path spread over its 5 s)
    s = np.arange(0.0, OLD.duration, 0.01)
    q, dq, _ = OLD.sample(s)
    k = int(np.flatnonzero([ssm_alpha_bound(ROBOT, a, b, NEAR, SSM) == 0.0 for a, b in zip(q, dq)])[0])
    assert s[k + 2] <= COST.reached(OLD, s[k + 2], NEAR, 0.3, stay=5.0) < s[k + 2] + 0.001


def test_a_robot_that_may_not_approach_a_person_who_stays_waits_until_they_go():
    # the shuttle runs into the no-approach distance of a person reaching over it (bound 0) at s_in; a
    # short move from rest that ends 10 ms of shuttle past s_in may not be finished while they stay: it
    # waits until the stay ends, so every second more of stay is a second more of time. (Floored like a
    # slow sample, its one zero-bound sample cost 50 times its 50 ms and no more: 6.12 s for a stay of 9 s
    # or of 15 s, as fast as a move that could be finished.)
    s = np.arange(0.0, OLD.duration, 0.01)
    q, dq, _ = OLD.sample(s)
    k = int(np.flatnonzero([ssm_alpha_bound(ROBOT, a, b, NEAR, SSM) == 0.0 for a, b in zip(q, dq)])[0])
    into = straight_line_trajectory(q[k - 10], q[k + 1], LIM.velocity, LIM.acceleration)
    t6, t9, t15 = (COST.trajectory_time(into, 0.0, NEAR, stay) for stay in (6.0, 9.0, 15.0))
    assert t9 - t6 == pytest.approx(3.0, abs=1e-9) and t15 - t9 == pytest.approx(6.0, abs=1e-9)
    assert 6.0 < t6 < 6.0 + into.duration          # the wait, then the rest at full speed
    # with no end to the stay the floor still gives a finite figure to compare
    assert np.isfinite(COST.trajectory_time(OLD, 0.0, NEAR)) and np.isfinite(COST.trajectory_time(into, 0.0, NEAR))


def test_polyline_trajectory_stops_exactly_at_every_corner():
    via = (Q_START + Q_GOAL) / 2 + np.array([0.0, 0.5, -0.5, 0.0, 0.0, 0.0])
    traj = polyline_trajectory(np.vstack([Q_START, via, Q_GOAL]), LIM.velocity, LIM.acceleration, version=3)
    corner = int(np.argmin(np.abs(traj.positions - via).max(axis=1)))
    assert np.allclose(traj.positions[corner], via) and np.allclose(traj.velocities[corner], 0.0)
    assert np.allclose(traj.positions[[0, -1]], [Q_START, Q_GOAL]) and traj.version == 3
    _, dq, _ = traj.sample(np.linspace(0.0, traj.duration, 2000))
    assert np.all(np.abs(dq) <= LIM.velocity + 1e-9)


def test_the_search_goes_round_a_person_who_stays_by_a_short_detour_and_is_repeatable():
    search = PathSearch(CM, COST, SearchOptions())
    direct = np.vstack([Q_START, Q_GOAL])
    found = search.search(Q_START, Q_GOAL, NEAR, np.random.default_rng(5), stay=5.0, seeds=(direct,))
    assert found is not None and search.free(found.waypoints, NEAR)
    assert np.allclose(found.waypoints[[0, -1]], direct)
    slowed = COST.path_time(direct, NEAR, 5.0)
    assert found.predicted < 0.8 * slowed                        # out of the slowdown ...
    assert COST.path_time(found.waypoints, None) < 1.8 * OLD.duration   # ... by a short way round
    again = search.search(Q_START, Q_GOAL, NEAR, np.random.default_rng(5), stay=5.0, seeds=(direct,))
    assert np.array_equal(again.waypoints, found.waypoints)      # the same seed, the same path
    # nobody near: the direct line itself is the fastest
    alone = search.search(Q_START, Q_GOAL, None, np.random.default_rng(5), seeds=(direct,))
    assert alone.origin == "seed 0" and len(alone.waypoints) == 2


def test_a_path_cannot_start_towards_a_person_inside_its_no_approach_distance_while_they_stay():
    # the robot stands inside the person's protective distance, and the first metres of this motion
    # approach them (the SSM allows no approach at all there), though a step further on it would not:
    # the scaling layer holds it until they leave, and the path's cost must say so as its trajectory's does
    q = Q_START + 0.35 * (Q_GOAL - Q_START)
    goal = np.array([2.171, -0.361, 0.895, -0.139, 0.391, 1.071])
    velocity = (goal - q) / COST.segment_time(q, goal)
    assert ssm_alpha_bound(ROBOT, q, velocity, NEAR, SSM) == 0.0
    assert ssm_alpha_bound(ROBOT, q + 0.025 / np.abs(goal - q).max() * (goal - q), velocity, NEAR, SSM) > 0.5
    timed = straight_line_trajectory(q, goal, LIM.velocity, LIM.acceleration)
    stay = 3.0
    path = COST.path_time(np.vstack([q, goal]), NEAR, stay)
    assert path > stay and path == pytest.approx(COST.trajectory_time(timed, 0.0, NEAR, stay), rel=0.05)
    assert np.array_equal(COST.path_samples(np.vstack([q, goal])).q[0], q)     # sampled from where it stands


def test_lifts_pass_over_an_arm_across_the_sweep_where_random_offsets_seldom_do():
    direct = np.vstack([Q_START, Q_GOAL])
    only_lifts = PathSearch(CM, COST, SearchOptions(candidates=0, refinements=0, escape_directions=0))
    found = only_lifts.search(Q_START, Q_GOAL, NEAR, np.random.default_rng(0), stay=5.0, seeds=(direct,))
    assert found.origin == "lift" and only_lifts.free(found.waypoints, NEAR)
    assert found.predicted < 0.8 * COST.path_time(direct, NEAR, 5.0)
    assert np.allclose(found.waypoints[:, 3:], Q_START[3:])        # the wrist as it is: the shoulder and elbow
    assert np.abs(found.waypoints[1:-1, 1:3] - Q_START[1:3]).max() > 0.2      # carry the arm over
    none = PathSearch(CM, COST, SearchOptions(candidates=0, refinements=0, escape_directions=0, lift_offsets=((), ()),
                                              raises=()))
    assert none.search(Q_START, Q_GOAL, NEAR, np.random.default_rng(0), stay=5.0, seeds=(direct,)).origin == "seed 0"


def test_a_raised_arm_is_chosen_past_a_person_standing_in_the_sweep_and_is_faster_when_executed():
    """Under the shipped model (a person may start to move), a person standing at the table's edge reaching into
    the middle of the sweep: the arm raised towards upright (shoulder raised, elbow opened) keeps every link near
    the base's axis, and beats the best lift (folded, over or under) by the cost and by a forward run of the
    scaling layer itself along both timed legs. Without the raises the search takes a lift."""
    from shared.planning.executed import ExecutedTime
    from shared.planning.timing import parameterize
    from shared.scaling.parameters import ScalingParameters

    shipped = LAID_OUT_SSM
    cost = SsmTimeCost(ROBOT, shipped)
    standing = person(-1.0, 0.0, 0.6, (-0.5, 0.0, 0.9))
    direct = np.vstack([Q_START, Q_GOAL])
    families = {"lifts": SearchOptions(candidates=0, refinements=0, escape_directions=0, raises=()),
                "both": SearchOptions(candidates=0, refinements=0, escape_directions=0)}
    found = {name: PathSearch(CM, cost, options).search(Q_START, Q_GOAL, standing, np.random.default_rng(0),
                                                        stay=5.0, seeds=(direct,))
             for name, options in families.items()}
    raised, lifted = found["both"], found["lifts"]
    assert raised.origin == "raise" and lifted.origin == "lift"
    assert raised.predicted < 0.95 * lifted.predicted < 0.8 * cost.path_time(direct, standing, 5.0)
    inner = raised.waypoints[1:-1]
    assert np.all(inner[:, 1] > Q_START[1] + 0.2) and np.all(inner[:, 2] < Q_START[2] - 0.5)    # raised, opened
    assert np.allclose(inner[:, 3:], Q_START[3:])
    executed = ExecutedTime(ROBOT, shipped, ScalingParameters())
    times = {name: executed.time(parameterize(result.waypoints, LIM, collision=CM), 0.0, standing, stay=5.0)
             for name, result in found.items()}
    assert times["both"] < 0.95 * times["lifts"]


def test_the_lifts_are_costed_right_after_the_seeds_so_a_cut_short_search_has_them():
    class Recording:                       # the search's cost, recording what it is asked, in order
        def __init__(self):
            self.asked, self.ssm = [], COST.ssm

        def path_time(self, waypoints, *args, **kwargs):
            self.asked.append(np.asarray(waypoints))
            return COST.path_time(waypoints, *args, **kwargs)

    recording = Recording()
    search = PathSearch(CM, recording, SearchOptions(refinements=0))
    direct = np.vstack([Q_START, Q_GOAL])
    search.search(Q_START, Q_GOAL, NEAR, np.random.default_rng(0), stay=5.0, seeds=(direct,))
    lifts = search._lifts(Q_START, Q_GOAL)
    assert np.array_equal(recording.asked[0], direct)
    assert all(np.array_equal(a, b) for a, b in zip(recording.asked[1:1 + len(lifts)], lifts))


def test_the_search_with_no_time_left_returns_the_best_path_found_so_far():
    search = PathSearch(CM, COST, SearchOptions(time_budget=0.0))
    direct = np.vstack([Q_START, Q_GOAL])
    found = search.search(Q_START, Q_GOAL, NEAR, np.random.default_rng(1), stay=5.0, seeds=(direct,))
    assert found is not None and search.free(found.waypoints, NEAR)
    assert found.costed < SearchOptions().candidates                 # cut short, yet an answer


def test_no_candidate_waypoint_is_put_on_a_joint_limit():
    """The lifts raise the elbow by up to 1.2 rad and the detours offset every joint: near a limit they are
    clipped, and clipped onto it the trajectory touched the limit and the driver clamped its commands. The
    waypoints between the ends stay LIMIT_MARGIN inside the joint ranges, the refinement's too."""
    from shared.planning.path_search import LIMIT_MARGIN
    search = PathSearch(CM, COST, SearchOptions())
    near = Q_START.copy()
    near[2] = LIM.upper[2] - 0.1                       # the elbow 0.1 rad below its limit: the lifts go past it
    rng = np.random.default_rng(3)
    candidates = search._lifts(near, Q_GOAL) + search._raises(near, Q_GOAL) + search._detours(near, Q_GOAL, rng, 72) \
        + search._escapes(near, Q_GOAL, NEAR, rng)
    inner = np.vstack([w[1:-1] for w in candidates])
    assert np.all(inner >= LIM.lower + LIMIT_MARGIN - 1e-12) and np.all(inner <= LIM.upper - LIMIT_MARGIN + 1e-12)
    assert np.isclose(inner[:, 2].max(), LIM.upper[2] - LIMIT_MARGIN)    # clipped, not dropped
    found = search.search(near, Q_GOAL, NEAR, np.random.default_rng(4), 5.0, (np.vstack([near, Q_GOAL]),))
    assert np.all(found.waypoints[1:-1] <= LIM.upper - LIMIT_MARGIN + 1e-12)
