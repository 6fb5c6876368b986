"""The hrc command line and the in-process demo of the paper's experiment (`hrc demo --sim`)."""

import json
import re
from dataclasses import replace
from pathlib import Path

import pytest

from evidence.scenarios import Q_GOAL, Q_START, paper_phases
from evidence.sim import run_shuttle
from shared.config import CellConfig, load_config
from shared.robot.model import default_robot
from tests.util import run_hrc

# The paper's configuration (deploy/cell-paper.yaml: its formula, the measured human speed held, and its planner,
# no posture): these tests hold the layers' logic on the paper's numbers and story; the shipped human model's own
# figures are tests/safety/test_ssm.py's and the cell's, the shipped planner's on the paper's phases below.
PAPER = load_config(Path(__file__).resolve().parents[2] / "deploy" / "cell-paper.yaml")


@pytest.mark.parametrize("args, text", [
    (["demo", "--duration", "-1"], "positive"),
    (["demo", "--duration", "nan"], "positive"),
    (["demo", "--duration", "soon"], "expected a number"),
    (["demo", "--config", "/nonexistent/cell.yaml"], "cannot read"),
    (["demo", "--no-planner"], "needs --sim"),
    (["demo", "--latency", "0.6"], "stale"),
    (["demo", "--latency", "-0.1"], "expected 0 to 0.5 s"),
    (["demo", "--sim", "--latency", "0.7"], "stale"),
    (["fly"], "invalid choice"),
])
def test_bad_arguments_exit_nonzero_with_a_clear_message(args, text):
    out = run_hrc(*args)
    assert out.returncode == 2
    assert text in out.stderr and "Traceback" not in out.stderr


def test_the_simulation_runs_with_a_cameras_latency_and_says_when_the_data_is_stale():
    """hrc demo --sim --latency 0.06 (the processes' option): the people come 60 ms late, older than the scripted
    person's 50 ms bound, so the robot stands and the operator is told why and what to raise."""
    out = run_hrc("demo", "--sim", "--no-planner", "--quiet", "--duration", "1", "--latency", "0.06")
    assert out.returncode == 0, out.stderr
    assert "hrc demo --sim: the people's data was stale in 94 % of the control cycles" in out.stdout
    summary = json.loads(out.stdout.strip().splitlines()[-1])
    assert summary["shuttle_progress"] == 0.0 and summary["tracker"]["capture_to_state_ms"]["p50"] == 60.0


def test_help_teaches_the_commands():
    out = run_hrc("--help")
    assert out.returncode == 0 and "hrc demo" in out.stdout


def test_the_paper_phases_in_simulation():
    result = run_shuttle(default_robot(), PAPER, paper_phases(6.0), Q_START, Q_GOAL, 24.0)
    assert result.violations == 0
    by_phase = {}
    for r in result.records:
        by_phase.setdefault(r.phase[0], []).append(r.step)
    assert min(s.alpha for s in by_phase["1"]) == pytest.approx(1.0)           # far away: full speed
    assert min(s.alpha for s in by_phase["2"]) < 0.8                            # approaching: scaled down
    assert by_phase["2"][-1].alpha == pytest.approx(1.0)                         # moving away: back up
    assert any(s.beta for s in by_phase["3"] + by_phase["4"])                    # in the path: replan request
    assert result.beta_requests >= 1 and result.shuttles >= 4


def test_the_paper_phases_with_both_layers():
    from shared.planning.collision import CollisionModel
    from shared.planning.ompl_planner import JointPlanner, PlannerOptions
    from shared.planning.replanner import Replanner, ReplanOptions
    from shared.planning.scene import DEFAULT_SCENE, load_scene

    robot, config = default_robot(), PAPER
    collision = CollisionModel(robot, load_scene(DEFAULT_SCENE), config.ssm.min_separation)
    paper = ReplanOptions(**config.planning.replan_fields())       # the paper's planner: no posture
    assert paper.posture_gap is None
    def both_layers(options: ReplanOptions):
        replanner = Replanner(collision, JointPlanner(collision, PlannerOptions(seed=1)), config.ssm, options=options)
        return run_shuttle(robot, config, paper_phases(6.0), Q_START, Q_GOAL, 24.0, replanner=replanner)

    scaling_only = run_shuttle(robot, config, paper_phases(6.0), Q_START, Q_GOAL, 24.0)
    # the paper's planner: the arm in the path (from 12 s) is gone round by a path planned for time under the SSM,
    # and the robot completes a shuttle more than with the scaling layer alone; every refusal says why
    # with both predicted times; no command comes closer than d_min
    result = both_layers(paper)
    assert result.violations == 0 and result.beta_requests > 0
    done = [(round(e.t, 2), e.reason) for e in result.replans if e.ok]
    # gone round by the planning layer: a replan taken, or the goal's own plan searched from rest while the arm is
    # there (in 10 runs, the phase period 0.5 % longer or shorter and planning charged 0 or 80 ms: a beta replan in 4,
    # the goal searched round the arm in 6; with the search waited for at every goal, a beta replan in 7 and in
    # 3 none at all, 0.08 shuttles less on average)
    searched = [round(g.t, 2) for g in result.goals if g.detail == "searched from rest"]
    assert any(t >= 12.0 and reason in ("horizon", "beta") for t, reason in done) \
        or any(12.0 <= t < 18.0 for t in searched), (done, result.goals)
    assert result.shuttles >= scaling_only.shuttles + 1 and result.progress >= scaling_only.progress + 0.3
    # (or, where the goal itself is out of reach while the person stays, that, with the link and distances)
    for refused in (e for e in result.replans if not e.ok):
        assert re.search(r"predicted \d+\.\d\d s, not .*faster than the old \d+\.\d\d s", refused.detail) \
            or "Error" in refused.detail or "merge" in refused.detail \
            or re.fullmatch(r"not searched: the goal is blocked while the person stays: there \w+ would be \d\.\d\d m "
                            r"from human capsule \d+, inside the \d\.\d\d m .*", refused.detail), refused.detail
    assert min(r.step.min_separation for r in result.records) >= 0.0
    # the paper's story: phase 3, the arm stays in the path from 13.8 s and the robot goes round it
    # and completes a shuttle; phase 4, the person steps closer (to 19.2 s) and reaches into the path: the
    # robot is not held there. Since the time law follows the searched detours' corners at speed, the plans
    # of phase 3 already keep it out of the person's slowdown in phase 4 (alpha never below alpha_min
    # there); wherever the scaling layer does hold it below alpha_min for longer than a replan request's
    # cooldown, a beta replan must take it on. Phase 4 with 3 s phases: below.
    def legs_between(run, start, end):
        return sum(1 for a, b in zip(run.records, run.records[1:]) if b.shuttles > a.shuttles and start <= b.t < end)
    # (the replan comes while the arm reaches into the path, 12-13.8 s, or once it is there: the scaling layer's stop
    # run ahead sees the arm coming by its tracked velocity and holds the robot from 13.48 s; without it, 14.5 s)
    assert any(12.0 <= t < 18.0 for t, _ in done) or any(12.0 <= t < 18.0 for t in searched), done
    assert legs_between(result, 13.8, 18.0) >= 1
    # the paper's replan request answered: a beta replan taken while the arm is in the path, phase 3, wherever the
    # scaling layer holds the robot there (below: every hold answered); where the goal's plan already goes round the
    # arm, nothing holds it (the goal left 12.8 s, the arm there since 12 s)
    assert any(12.0 <= t < 18.0 and why == "beta" for t, why in done) or any(12.0 <= t < 18.0 for t in searched), done
    assert legs_between(result, 19.2, 22.8) >= 1
    def holds_answered(run, start, end):    # every hold below alpha_min from start to end: short, or a beta replan
        taken = [e.t for e in run.replans if e.ok and e.reason == "beta"]
        held_from, holds = None, []
        for rec in (r for r in run.records if start <= r.t < end):
            if rec.step.alpha < config.scaling.alpha_min and held_from is None:
                held_from = rec.t
            elif rec.step.alpha >= config.scaling.alpha_min and held_from is not None:
                holds.append((held_from, rec.t))
                held_from = None
        if held_from is not None:            # still held when the phase ends
            holds.append((held_from, end))
        for a, b in holds:
            assert b - a <= 0.5 or any(a <= t <= b for t in taken), (a, b, run.replans)

    holds_answered(result, 12.0, 22.8)
    # phase 4 at 12 s (3 s phases): the scaling layer alone stays held beside the person until the end;
    # with both layers the robot reaches its goal while the person still reaches in. Where alpha falls below
    # alpha_min and the scaling layer asks for a replan, a new plan takes the robot on (the replan's own
    # leg is asserted); where the goal planned before already goes round the person, no hold goes
    # unanswered. (Before the search drew its candidates by the goal alone, a replan was taken in this run;
    # over 15 runs with the phase period 0.5 % longer or shorter and planning charged 0 to 90 ms, one was
    # taken and led to the goal in 6 of them, the goal reached in phase 4 in 9; now no replan is needed in
    # any, and the goal is reached in all 15.)
    fast = run_shuttle(robot, config, paper_phases(3.0), Q_START, Q_GOAL, 12.0, replanner=Replanner(
        collision, JointPlanner(collision, PlannerOptions(seed=1)), config.ssm, options=paper))
    fast_alone = run_shuttle(robot, config, paper_phases(3.0), Q_START, Q_GOAL, 12.0)
    assert legs_between(fast_alone, 9.0, 12.0) == 0 and fast.violations == 0
    assert legs_between(fast, 9.0, 12.0) >= 1
    taken = [e.t for e in fast.replans if e.ok and e.reason == "beta" and 9.0 <= e.t < 11.4]
    assert not taken or legs_between(fast, taken[0], 12.0) >= 1, fast.replans
    holds_answered(fast, 9.0, 11.4)
    # without the replan requests (the paper's ablation) and with the scaling layer alone, the robot is held
    # beside the arm until the person leaves
    no_beta = run_shuttle(robot, config, paper_phases(6.0), Q_START, Q_GOAL, 24.0, beta_replans=False,
                          replanner=Replanner(collision, JointPlanner(collision, PlannerOptions(seed=1)), config.ssm,
                                              options=paper))
    assert legs_between(no_beta, 13.8, 22.8) == 0 and legs_between(scaling_only, 13.8, 22.8) == 0
    assert no_beta.violations == 0
    # pure ski rental (no patience): never slower than the scaling layer alone
    assert both_layers(replace(paper, patience=0.0)).progress >= scaling_only.progress - 1e-9


@pytest.mark.parametrize("period", [6.0, 3.0])
def test_the_shipped_planner_does_at_least_what_the_papers_does_on_its_own_phases(period):
    """The shipped planning layer (its folded posture while someone is within 2.5 m of the robot's reach) on the
    paper's phases under the paper's formula, side by side with the paper's planner: where the paper's planner
    replans round the reaching arm, the folded leg already clears it, and the robot does at least as much
    (measured: 9 against 8 shuttles in 24 s, progress 9.11 against 8.94; 4 against 3 in 12 s), with no violation
    and no command closer than d_min."""
    from shared.planning.collision import CollisionModel
    from shared.planning.ompl_planner import JointPlanner, PlannerOptions
    from shared.planning.replanner import Replanner, ReplanOptions
    from shared.planning.scene import DEFAULT_SCENE, load_scene

    robot = default_robot()
    collision = CollisionModel(robot, load_scene(DEFAULT_SCENE), PAPER.ssm.min_separation)
    shipped = ReplanOptions(**CellConfig().planning.replan_fields())
    paper = ReplanOptions(**PAPER.planning.replan_fields())
    assert shipped.posture_gap == 2.5 and paper.posture_gap is None
    def run(options: ReplanOptions):
        replanner = Replanner(collision, JointPlanner(collision, PlannerOptions(seed=1)), PAPER.ssm, options=options)
        return run_shuttle(robot, PAPER, paper_phases(period), Q_START, Q_GOAL, 4 * period, replanner=replanner)

    ours, theirs = run(shipped), run(paper)
    assert ours.violations == 0 and min(r.step.min_separation for r in ours.records) >= 0.0
    assert ours.shuttles >= theirs.shuttles and ours.progress >= theirs.progress, (ours.progress, theirs.progress)
    # phase 3's legs are the folded ones (the elbow up by the fold on the way), which clear the reaching arm
    folded = [r for r in ours.records if r.phase[0] == "3"]
    assert folded and max(r.step.q_command[2] - Q_START[2] for r in folded) > 0.5
