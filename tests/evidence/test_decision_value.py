"""bench/decision_value.py: each replan's worth, by the run without it (the figures are the benchmark's)."""

import pytest

from tests.util import load_bench

bench = load_bench("decision_value")


def test_a_decision_is_named_by_its_action_and_start_and_its_predicted_saving_read_from_its_detail():
    assert bench.decision_kind("beta", "replan request, from rest: predicted 3.20 s instead of 3.68 s") == \
        "beta from rest"
    assert bench.decision_kind("slow", "path predicted slow, merged at s=0.11: predicted 2 s") == "slow merged"
    assert bench.decision_kind("search", "anything") == "search"
    assert bench.predicted_saving("from rest: predicted 3.20 s instead of 3.68 s") == pytest.approx(0.48)
    assert bench.predicted_saving("vetoed") is None


def test_the_table_sums_values_and_splits_paid_from_cost():
    scenarios = [{"decisions": [
        {"action": "beta", "detail": "from rest: predicted 3.00 s instead of 4.00 s", "value": 0.5},
        {"action": "beta", "detail": "from rest: predicted 3.00 s instead of 3.50 s", "value": -0.2},
        {"action": "beta", "detail": "from rest: predicted 3.00 s instead of 3.10 s", "value": 0.005},
        {"action": "horizon", "detail": "path blocked, merged at s=1: predicted 2.00 s instead of 2.20 s",
         "value": -0.1}]}]
    rows = bench.table(scenarios)
    assert rows["beta from rest"] == {"taken": 3, "value": 0.305, "mean": pytest.approx(0.1017, abs=1e-4),
                                      "paid": 1, "cost": 1, "saving_paid": 1.0, "saving_cost": 0.5}
    assert rows["horizon"]["taken"] == 1 and rows["horizon"]["cost"] == 1 and rows["horizon"]["paid"] == 0


def test_one_scenario_is_run_without_each_replan_and_without_all():
    """Two people, seed 4000: one beta replan from rest; its value is what the run with it made more than the run
    without it, and with only one replan the run without any is that same run."""
    got = bench.one(("two_humans", 4000, 12.0, "full"))
    assert got["violations"] == 0 and len(got["decisions"]) == 1
    only = got["decisions"][0]
    assert only["action"] == "beta" and "from rest" in only["detail"] and abs(only["value"]) > 0.01
    assert got["shuttles"] - got["without_any"] == pytest.approx(only["value"], abs=1e-3)
    # each new goal's leg held against the fold and the line, but not against itself
    assert got["goals"] and all(set(g["against"]) <= {"fold", "line"} and g["against"] for g in got["goals"])
    assert all("fold" not in g["against"] for g in got["goals"] if g["detail"] == "the folded leg")
    assert all("line" not in g["against"] for g in got["goals"] if g["detail"] == "the straight line")


def test_the_goal_table_sums_each_chosen_legs_value_against_the_fold_and_the_line():
    scenarios = [{"goals": [
        {"detail": "the folded leg", "against": {"line": 0.2}},
        {"detail": "the folded leg", "against": {"line": -0.05}},
        {"detail": "the straight line", "against": {"fold": -0.3}},
        {"detail": "searched from rest: predicted 3 s", "against": {"fold": 0.1, "line": 0.0}}]}]
    rows = bench.goal_table(scenarios)
    assert rows["the folded leg"]["chosen"] == 2 and rows["the folded leg"]["fold"]["held"] == 0
    assert rows["the folded leg"]["line"] == {"held": 2, "value": 0.15, "paid": 1, "cost": 1}
    assert rows["the straight line"]["fold"] == {"held": 1, "value": -0.3, "paid": 0, "cost": 1}
    assert rows["searched from rest"]["line"] == {"held": 1, "value": 0.0, "paid": 0, "cost": 0}
