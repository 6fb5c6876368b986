"""The scaler's path steps once per SYNC however the joint states come (shared.scaling.sync_clock)."""

from shared.scaling.sync_clock import RESTART_GAP, SyncClock


def run(events):
    """events: ints (a state for that SYNC: it ticks if it wakes one) and 'fallback' (a tick without a state).
    Returns the SYNC the path stepped for at each tick."""
    clock, steps = SyncClock(), []
    for e in events:
        if e == "fallback" or clock.arrived(e):
            clock.ticked()
            steps.append(clock.stepped)
    return steps


def test_one_step_per_sync_when_every_sync_is_answered():
    assert run([1, 2, 3, 4]) == [1, 2, 3, 4]


def test_a_late_state_after_the_fallback_stood_in_for_it_wakes_no_tick():
    """SYNC 3 not answered: the fallback steps for it, its late state (published just before SYNC 4) and a
    second answer to SYNC 4 do not step again. Before, 2, fallback, 3, 4 were four steps for three SYNCs."""
    assert run([1, 2, "fallback", 3, 4, 4, 5]) == [1, 2, 3, 4, 5]


def test_the_late_state_without_a_fallback_steps_once():
    assert run([1, 2, 3, 4, 5]) == [1, 2, 3, 4, 5]
    assert run([1, 2, 4, 5]) == [1, 2, 4, 5]          # a SYNC whose state never came is not stepped twice


def test_a_silent_driver_goes_on_on_the_fallback_and_a_restarted_one_is_followed():
    steps = run([10, "fallback", "fallback", "fallback"])
    assert steps == [10, 11, 12, 13]
    many = ["fallback"] * (RESTART_GAP + 5)
    steps = run([100, *many, 0, 1, 2])                  # a new driver counts from 0 again
    assert steps[-3:] == [0, 1, 2]
    assert run([100, 90, 101]) == [100, 101]            # a little behind is a late state, not a restart


def test_states_without_a_number_always_tick():
    assert run([None, None, None]) == [None] * 3        # each steps the path; the clock has no number to keep
    clock = SyncClock()
    assert clock.arrived(None) and clock.arrived(None)
