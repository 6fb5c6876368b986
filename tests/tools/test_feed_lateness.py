"""The person feed's lateness figures (tools.actors.HumanFeed): how late it woke for its samples, p99 and max, from
a bounded histogram, so that a feed the machine did not run in time shows in the demo's summary."""

from tools.actors import LATE_LIMIT, HumanFeed


class _Session:
    def declare_publisher(self, key):
        return None


class _Still:
    rate = 100.0

    def at(self, t):
        return None


def _feed() -> HumanFeed:
    from shared.wire.keys import KeySpace

    return HumanFeed(_Session(), KeySpace("t/late"), _Still(), 0.0)


def test_no_wake_up_no_figures():
    assert _feed().lateness_figures() == {"late_ms_p99": None, "late_ms_max": None, "late_max_at_s": None}


def test_p99_and_max_from_the_histogram():
    feed = _feed()
    for _ in range(990):
        feed.lateness.add(0.0003)                 # 0.3 ms late
    for _ in range(10):
        feed.lateness.add(0.056)                  # a 56 ms stall
    figures = feed.lateness_figures()
    assert 0.3 <= figures["late_ms_p99"] <= 0.4 + 1e-9 and figures["late_ms_max"] == 56.0
    feed.lateness.add(0.056)                      # now more than 1 % are late: the p99 moves to them
    feed.lateness.add(0.057)
    assert 56.0 <= feed.lateness_figures()["late_ms_p99"] <= 56.1 + 1e-9


def test_later_than_the_histogram_is_the_max_and_early_counts_as_on_time():
    feed = _feed()
    feed.lateness.add(-0.001)                     # woke a hair early: on time
    assert feed.lateness.counts[0] == 1
    for _ in range(5):
        feed.lateness.add(LATE_LIMIT + 0.5)                # later than 200 ms
    figures = feed.lateness_figures()
    assert figures["late_ms_p99"] == figures["late_ms_max"] == round(1e3 * (LATE_LIMIT + 0.5), 1)
