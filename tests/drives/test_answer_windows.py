"""Which SYNC a drive's answer belongs to, by its frame's stamp (shared.drives.answer_windows)."""

from shared.drives.answer_windows import JUDGE_AFTER, AnswerWindows

P = 0.01
T0 = 1_700_000_000.0           # the wall clock, as the interfaces stamp frames


def synced(windows: AnswerWindows, number: int) -> float:
    wall = T0 + number * P
    windows.sync(number, wall)
    return wall


def test_a_sync_every_drive_answered_in_its_window_is_answered_and_one_a_drive_missed_is_not():
    w = AnswerWindows(nodes=3, period=P)
    t = synced(w, 1)
    assert [w.answer(k, t + 1e-4) for k in range(3)] == [1, 1, 1]
    assert w.take() == []                               # its window is still open
    t = synced(w, 2)
    w.answer(0, t + 1e-4)                               # read: every frame stamped before it has been read
    w.answer(1, t + 2e-4)                               # node 2's answer to SYNC 2 is lost
    assert w.take() == [True]
    t = synced(w, 3)
    assert w.take() == []                               # nothing read from SYNC 3's window yet
    w.answer(0, t + 1e-4)
    assert w.take() == [False]


def test_an_answer_read_late_counts_for_its_own_sync_not_the_next():
    w = AnswerWindows(nodes=2, period=P)
    t1 = synced(w, 1)
    t2 = synced(w, 2)                                   # the driver sent SYNC 2 before reading SYNC 1's answers
    assert w.answer(0, t1 + 1e-4) == 1 and w.answer(1, t1 + 2e-4) == 1
    assert w.answer(0, t2 + 1e-4) == 2 and w.answer(1, t2 + 1e-4) == 2
    synced(w, 3)
    w.answer(0, T0 + 3 * P + 1e-4)
    assert w.take() == [True, True]


def test_a_window_nobody_reads_is_judged_missed_after_judge_after_periods():
    """A receive thread that far behind is a lost answer: the positions it would give are that old."""
    w = AnswerWindows(nodes=1, period=P)
    synced(w, 1)
    for n in range(2, JUDGE_AFTER + 2):
        synced(w, n)
    assert w.take() == []                               # SYNC 1's window closed JUDGE_AFTER - 1 periods ago
    synced(w, JUDGE_AFTER + 2)
    assert w.take() == [False]
    assert w.answer(0, T0 + P + 1e-4) == 1 and w.take() == []      # read at last: judged already, not twice


def test_stamps_on_another_clock_make_the_windows_unusable():
    w = AnswerWindows(nodes=1, period=P)
    synced(w, 1)
    assert w.usable and w.answer(0, 12_345.6) is None and not w.usable       # a monotonic stamp
    w = AnswerWindows(nodes=1, period=P)
    synced(w, 1)
    assert w.answer(0, None) is None and not w.usable
    w = AnswerWindows(nodes=1, period=P)
    assert w.answer(0, T0) is None and w.usable           # no SYNC sent yet: nothing to place it in


def test_a_restarted_sync_count_judges_nothing_from_before_it():
    w = AnswerWindows(nodes=1, period=P)
    synced(w, 5)
    synced(w, 6)
    w.sync(1, T0 + 7 * P)
    w.answer(0, T0 + 7 * P + 1e-4)
    w.sync(2, T0 + 8 * P)
    w.answer(0, T0 + 8 * P + 1e-4)
    assert w.take() == [True]
