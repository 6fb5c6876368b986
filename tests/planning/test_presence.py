"""How long the people have stayed (shared.planning.presence): the dwell clock, pure."""

import numpy as np
import pytest

from shared.core.humans import HumanCapsules
from shared.planning.presence import DWELL_RADIUS, DWELL_SPEED, DwellClock, StillClock, centroid_motion

TORSO = [[-0.9, 0.0, 0.9], [-0.9, 0.0, 1.35]]


def worker(t: float, shift=(0.0, 0.0, 0.0), hand_speed: float = 0.4, walk=(0.0, 0.0, 0.0)) -> HumanCapsules:
    """A person at a table's edge: the torso where it is (moved by `shift` and on at the `walk` velocity, m/s), a
    forearm reaching in and out every 2 s, its hand at up to `hand_speed` (m/s; 0.25 m in at 0.4 m/s)."""
    base = np.asarray(shift) + np.asarray(walk) * t
    reach = hand_speed / np.pi * (1.0 - np.cos(np.pi * t))
    hand_v = hand_speed * np.sin(np.pi * t)
    segments = np.array([TORSO, [[-0.75, 0.2, 1.1], [-0.55 + reach, 0.2, 0.9]]]) + base
    velocities = np.array([[walk, walk], [walk, np.add(walk, (hand_v, 0.0, 0.0))]], dtype=float)
    return HumanCapsules(segments, np.array([0.2, 0.05]), velocities, np.array([True, True]))


def test_the_centroid_and_its_speed_are_of_every_end_point():
    centre, speed = centroid_motion(worker(0.5, walk=(0.4, 0.0, 0.0)))
    assert centre[1] == pytest.approx(0.1) and speed > 0.4     # the hand moves too, the same way at t = 0.5
    assert centroid_motion(HumanCapsules.from_arrays([TORSO], [0.2]))[1] == 0.0   # no velocity known: none


def test_someone_working_in_place_dwells_while_their_hands_move_and_the_still_clock_does_not_count():
    dwell, still = DwellClock(), StillClock()
    for k in range(31):
        t = 0.1 * k
        dwell.update(t, worker(t))
        still.update(t, worker(t))
    assert dwell.waited(3.0) == pytest.approx(2.9)      # from the second sample: the first settles them
    assert still.waited(3.0) < 1.0                      # the reaching hand starts it again and again


def test_a_walker_a_step_away_and_nobody_in_view_start_the_dwell_again():
    dwell = DwellClock()
    for k in range(31):                                  # walking at 0.5 m/s: never settled
        t = 0.1 * k
        dwell.update(t, worker(t, walk=(0.5, 0.0, 0.0), hand_speed=0.0))
    assert dwell.waited(3.0) == 0.0
    away = (DWELL_RADIUS + 0.05, 0.0, 0.0)
    for t, shift in ((3.1, (0.0, 0.0, 0.0)), (3.2, (0.0, 0.0, 0.0)), (3.3, (0.0, 0.0, 0.0))):
        dwell.update(t, worker(t, shift=shift, hand_speed=0.0))      # stopped: settled at 3.1, dwelling from 3.2
    assert dwell.waited(3.3) == pytest.approx(0.1)
    dwell.update(3.4, worker(3.4, shift=away, hand_speed=0.0))        # a step away: settled anew there
    assert dwell.waited(3.4) == 0.0
    for t in (3.5, 3.6):
        dwell.update(t, worker(t, shift=away, hand_speed=0.0))
    assert dwell.waited(3.6) == pytest.approx(0.1)
    dwell.update(3.7, None)
    assert dwell.waited(3.7) == 0.0
    dwell.update(3.8, HumanCapsules.empty())
    assert dwell.waited(3.8) == 0.0


def test_a_person_seen_twice_in_one_state_still_dwells_and_stepping_in_slowly_is_not_settling():
    dwell = DwellClock()
    for k in range(11):
        t = 0.1 * k
        one = worker(t)
        dwell.update(t, HumanCapsules.union([one, one]) if k % 2 else one)      # twice the capsules, same place
    assert dwell.waited(1.0) == pytest.approx(0.9)
    creeping = DwellClock()
    for k in range(11):                                  # the paper's phase 4: a step in just above standing speed
        t = 0.1 * k
        creeping.update(t, worker(t, walk=(DWELL_SPEED + 0.02, 0.0, 0.0), hand_speed=0.0))
    assert creeping.waited(1.0) == 0.0


def test_a_malformed_state_is_never_a_dwell_and_the_clock_recovers_after_it():
    """Planning only, but a NaN that slipped through must not stretch the people's stay: not dwelling, then settled
    anew at the next good state."""
    dwell = DwellClock()
    for t in (0.0, 0.1, 0.2):
        dwell.update(t, worker(t, hand_speed=0.0))
    bad = worker(0.3, hand_speed=0.0)
    bad.segments[0, 0, 0] = np.nan
    dwell.update(0.3, bad)
    assert dwell.waited(0.3) == 0.0
    for t in (0.4, 0.5, 0.6):
        dwell.update(t, worker(t, hand_speed=0.0))
    assert dwell.waited(0.6) == pytest.approx(0.1)
