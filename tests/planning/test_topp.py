"""The compiled TOPP-RA (shared.planning.topp) against toppra's own, the well-kept implementation of the
same algorithm: the same laws on random paths and start speeds, the same refusals."""

import numpy as np
import toppra

from shared.planning.timing import chord_points, chord_spline
from shared.planning.topp import TimeLaw, fastest_law, toppra_law
from shared.robot.model import default_robot

LIM = default_robot().limits


def _random_path(rng: np.random.Generator):
    """A cubic spline through 2-5 random waypoints (densified like the smoothings), chord-length."""
    waypoints = rng.uniform(LIM.lower * 0.6, LIM.upper * 0.6, size=(int(rng.integers(2, 6)), 6))
    pts, chord = chord_points(waypoints, (np.inf, 0.5, 0.25)[int(rng.integers(3))])
    d_start = (pts[1] - pts[0]) / chord[1]
    return chord_spline(pts, chord, d_start), chord, d_start


def test_the_compiled_law_is_toppras_law_and_refuses_what_toppra_refuses():
    rng = np.random.default_rng(7)
    velocity, acceleration = LIM.velocity, LIM.acceleration * 0.9
    refused = compared = 0
    for _ in range(60):
        path, chord, d_start = _random_path(rng)
        top = float(np.min(velocity / np.maximum(np.abs(d_start), 1e-9)))      # the fastest start allowed
        start = 0.0 if rng.random() < 0.3 else rng.uniform(0.5, 1.3) * top
        grid = np.linspace(0.0, chord[-1], 201)
        theirs = toppra_law(path, grid, velocity, acceleration, start)
        ours = fastest_law(path, grid, velocity, acceleration, start)
        assert (ours is None) == (theirs is None), f"start {start:.3f} of {top:.3f}"
        if ours is None:
            refused += 1
            continue
        compared += 1
        assert abs(ours.duration / theirs.duration - 1.0) < 1e-6
        t = np.linspace(0.0, ours.duration, 97)
        s, speed = ours.at(t)
        assert np.allclose(path(s), theirs(t), atol=1e-5)
        assert np.allclose(path(s, 1) * speed[:, None], theirs(t, 1), atol=1e-4)
    assert refused >= 5 and compared >= 30          # both outcomes were exercised


def test_a_law_keeps_the_limits_at_its_grid_points_and_starts_and_ends_as_asked():
    path, chord, _ = _random_path(np.random.default_rng(3))
    grid = np.linspace(0.0, chord[-1], 201)
    law = fastest_law(path, grid, LIM.velocity, LIM.acceleration, 0.0)
    assert law.speed[0] == 0.0 and law.speed[-1] == 0.0 and np.all(np.diff(law.times) > 0.0)
    dq, ddq = path(grid, 1), path(grid, 2)
    assert np.all(np.abs(dq * law.speed[:, None]) <= LIM.velocity * (1 + 1e-6))
    q_acc = dq[:-1] * law.acceleration[:, None] + ddq[:-1] * law.speed[:-1, None] ** 2
    assert np.all(np.abs(q_acc) <= LIM.acceleration * (1 + 1e-6))
    s, speed = law.at(np.array([0.0, law.duration, law.duration + 1.0]))
    assert np.allclose(s, [0.0, chord[-1], chord[-1]], atol=1e-9) and abs(speed[1]) < 1e-6


def test_a_constant_acceleration_law_between_grid_points_samples_exactly():
    law = TimeLaw(np.array([0.0, 1.0, 2.0]), np.array([0.0, 2.0, 0.0]))   # 2 up at +2, then down at -2
    assert np.allclose(law.times, [0.0, 1.0, 2.0]) and np.allclose(law.acceleration, [2.0, -2.0])
    s, speed = law.at(np.array([0.5, 1.5]))
    assert np.allclose(s, [0.25, 1.75]) and np.allclose(speed, [1.0, 1.0])


def test_a_law_stuck_at_rest_is_no_law():
    """Two grid points at rest in a row never get on: an infinite duration, which fastest_law refuses."""
    assert not np.isfinite(TimeLaw(np.array([0.0, 1.0, 2.0]), np.zeros(3)).duration)
    straight = toppra.SplineInterpolator(np.array([0.0, 1.0]), np.array([np.zeros(6), np.full(6, 0.5)]))
    assert fastest_law(straight, np.linspace(0.0, 1.0, 11), LIM.velocity, np.zeros(6), 0.0) is None
    assert fastest_law(straight, np.linspace(0.0, 1.0, 11), LIM.velocity, LIM.acceleration, 0.0) is not None


def test_the_planning_bench_times_both_laws_on_a_detour():
    """bench/planning.py's side-by-side (the figures are the bench's, not asserted): both laws time the same
    bent path, to the same duration."""
    from evidence.scenarios import Q_GOAL, Q_START
    from tests.util import load_bench
    ours_ms, theirs_ms, differ = load_bench("planning").time_laws(
        np.vstack([Q_START, (Q_START + Q_GOAL) / 2 + np.array([0.0, 0.4, -0.3, 0.2, 0.0, 0.0]), Q_GOAL]), LIM)
    assert ours_ms > 0.0 and theirs_ms > 0.0 and differ < 1e-6
