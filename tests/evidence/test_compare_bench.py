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




def test_the_seconds_stopped_and_slowed_are_per_scenario_and_add_up_to_at_most_its_length():
    """aggregate: seconds stopped and seconds slowed (moving below full speed) per scenario, from each run's
    shares of its cycles; they never overlap, so together at most the scenario's length."""
    def run_of(stopped: float, slowed: float) -> dict:
        return {"shuttles": 1.0, "completed": 1, "duration_s": 12.0, "stopped_fraction": stopped,
                "slowed_fraction": slowed, "min_margin_m_s": 0.1, "violations": 0, "command_exceedances": 0,
                "wall_s": 0.1}
    rows = [{"kind": "standing", **{s: run_of(*shares) for s in ("zones", "scale_only", "full")}}
            for shares in ((0.5, 0.25), (0.0, 0.5))]
    per = load_bench("compare").aggregate(rows, 0.1)["full"]
    assert per["stopped_s"] == 3.0 and per["slowed_s"] == 4.5 and per["stopped_s"] + per["slowed_s"] <= 12.0


def test_a_run_says_the_share_of_its_cycles_spent_slowed_apart_from_stopped():
    from evidence.strategies import Strategies
    from shared.planning.scene import DEFAULT_SCENE, load_scene

    s = Strategies(scene=load_scene(DEFAULT_SCENE)).run("scale_only", "standing", 1, 4.0).summary()
    assert 0.0 <= s["slowed_fraction"] <= 1.0 - s["stopped_fraction"]
    assert s["slowed_fraction"] + s["stopped_fraction"] > 0.0          # someone stands in the way: not at full speed
