"""bench/compare.py's command line and its ratios (the figures themselves are the benchmark's, not asserted)."""



from evidence.stats import PairedRatio
from tests.util import load_bench


def row(zones: float, scale_only: float, full: float) -> dict:
    return {"kind": "standing", "zones": {"shuttles": zones}, "scale_only": {"shuttles": scale_only},
            "full": {"shuttles": full}}


def test_a_strategy_that_did_nothing_gives_a_reason_not_a_crash():
    ratios = load_bench("compare").ratios([row(0.0, 1.0, 2.0), row(0.0, 2.0, 2.0)])
    assert isinstance(ratios["full/scale_only"], PairedRatio) and abs(ratios["full/scale_only"].ratio - 4 / 3) < 1e-12
    assert ratios["full/zones"].startswith("no ratio: ") and "did nothing" in ratios["full/zones"]


def test_won_back_is_the_share_of_what_the_people_cost_scaling_alone():
    won_back = load_bench("compare").won_back
    per = {"scale_only": {"shuttles_per_min": 16.0}, "full": {"shuttles_per_min": 19.0}}
    assert abs(won_back(per, 25.0) - 3.0 / 9.0) < 1e-3                       # 3 of the 9 lost
    assert won_back(per | {"full": {"shuttles_per_min": 15.0}}, 25.0) < 0    # worse than scaling alone
    assert won_back(per, 16.0) is None                                        # the people cost nothing


