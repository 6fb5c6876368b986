"""The fault campaign's CAN requests: retried, and a clear error (never a traceback) when unanswered."""

import canopen
import pytest

from tools.faults import CanProbe, InjectionError


class FlakyEntry:
    def __init__(self, failures: int) -> None:
        self.failures, self.writes = failures, []

    @property
    def raw(self):
        return None

    @raw.setter
    def raw(self, value):
        if self.failures > 0:
            self.failures -= 1
            raise canopen.SdoCommunicationError("No SDO response received")
        self.writes.append(value)


def probe_with(entry: FlakyEntry) -> CanProbe:
    probe = CanProbe.__new__(CanProbe)                 # no bus: only the request logic is under test
    probe.nodes = {5: type("Node", (), {"sdo": {0x2F00: {2: entry}}})()}
    return probe


def test_an_unanswered_request_is_tried_again():
    entry = FlakyEntry(failures=2)
    probe_with(entry).inject(5, 2, 1)
    assert entry.writes == [1]


def test_a_request_never_answered_is_a_clear_error():
    with pytest.raises(InjectionError, match=r"node 5: SDO write 0x2F00:2 = 1 not answered after 3 tries"):
        probe_with(FlakyEntry(failures=10)).inject(5, 2, 1)


def test_the_campaign_estimates_the_time_left_from_the_faults_done():
    from tools.faults import time_left
    assert time_left(0, 12, 0.0) == ""
    assert time_left(3, 12, 60.0) == " (60 s so far, about 180 s left)"
    assert time_left(12, 12, 240.0).endswith("about 0 s left)")
