"""The three speed-and-separation strategies compared side by side, on the same simulation and cores.

* zones: zone-based SSM as deployed today (evidence.zones), the fixed straight shuttle, no replanning;
* scale_only: the scaling layer on the fixed straight shuttle (the paper's ablation);
* full: the scaling layer and the planning layer (horizon replans, beta replans, every shuttle planned
  around the humans), each path search charged the planner service's wall-clock budget for it (80 ms)
  on the simulated clock: repeatable, and no kinder than the cell, where searches stop at that budget;
* foresight (a bound, not a strategy a cell can run; ``bench/compare.py --foresight``): full, with the
  planning layer told the scripted people's own future instead of its constant-velocity forecast
  (``evidence.foresight``): the most a better prediction of human motion could add to full;
* oracle (``bench/compare.py --oracle``): foresight with a search eight times as large, planning free of time and
  every predicted gain taken (``evidence.foresight.oracle_options``): this planning layer at its most. A reference,
  not a bound: it ranks its choices by a prediction and falls as its search grows (``bench/bound_search.py``);
* clairvoyant (a bound that runs the real scaling layer; ``bench/compare.py --clairvoyant``): the best sequence of
  fixed leg shapes, one per leg, found by running the whole scenario with each (``evidence.clairvoyant``): never
  below scale_only or fixed_path on the same scenario, and rising with its search by construction;
* fixed_path (``bench/compare.py --fixed-path``): the scaling layer on one fixed path chosen once, the shuttle with
  the elbow folded over the middle of the sweep (``evidence.fixed_path``), no planning: the strongest simple
  baseline the planning layer must beat;
* scale_only_paper, full_paper (``bench/compare.py --paper``), fixed_path_paper (with ``--fixed-path`` too): the
  same under the paper's formula (the measured human speed held), judged, as every run, by the shipped model's
  monitor; "full_paper/scale_only_paper" and "full_paper/fixed_path_paper" are the planning layer's figures
  under that formula, as the issue's goals ask for them with the paper's formula too.
Every run is judged by the independent monitor's rule (evidence.sim). A run may have the people reach the cell
``latency`` s after their capture (a camera pipeline's; ``run_shuttle(latency=)``): every strategy is given them that
late, the zones are sized for it (``SpeedZones.sized(latency=)``), and the judge checks the people of each moment.
``Strategies`` builds the robot, the collision model and the planner once per process and runs any (strategy,
scenario) on them, and the shuttle in an empty cell (``empty_cell``): the most any strategy can do in a scenario's
time.
"""

from __future__ import annotations

import numpy as np

from evidence.clairvoyant import SEARCHES, Choice, EpisodeRuns, LegSequence, ShapedLegs, greedy_sequence, nested_searches
from evidence.fixed_path import FixedPath
from evidence.foresight import ORACLE_SEARCH, Foresight, foresight_options, oracle_options
from evidence.scenarios import Q_GOAL, Q_START, EmptyCell, make_scenario
from evidence.sim import GoalLeg, SimResult, Veto, run_shuttle
from evidence.zones import SpeedZones, ZoneScalingLayer, fastest_point_speed
from shared.config import CellConfig
from shared.core.trajectory import straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.forecast import Forecaster
from shared.planning.ompl_planner import JointPlanner, PlannerOptions
from shared.planning.options import ReplanOptions
from shared.planning.path_search import CELL_BUDGET
from shared.planning.replanner import Replanner
from shared.planning.scene import Scene
from shared.robot.model import default_robot
from shared.safety.monitor import SafetyMonitor
from shared.scaling.layer import ScalingLayer

STRATEGIES = ("zones", "scale_only", "full")
BOUNDS = ("foresight", "oracle", "clairvoyant")
# the same two layers under the paper's formula (the measured human speed held; ``bench/compare.py --paper``),
# judged by the shipped model's monitor: what the shipped model costs, and what the formula lets through
PAPER = ("scale_only_paper", "full_paper")
BASELINES = ("fixed_path",)
PAPER_BASELINES = ("fixed_path_paper",)     # the fixed path under the paper's formula (--paper --fixed-path)
KNOWN = STRATEGIES + BASELINES + BOUNDS + PAPER + PAPER_BASELINES    # every name ``Strategies.run`` takes, in order


class Strategies:
    def __init__(self, config: CellConfig | None = None, scene: Scene | None = None, planner_seed: int = 1,
                 forecaster: Forecaster | None = None, oracle_search: int = ORACLE_SEARCH,
                 oracle_judge: str = "cost") -> None:
        """forecaster: the full strategy's forecast of the people (None: the planning layer's default,
        ``ConstantVelocity``): a researcher's predictor, measured on the same scenarios. oracle_search: how
        many times the planning layer's search the oracle bound searches; oracle_judge: what its decisions are
        predicted by (``ReplanOptions.judge``)."""
        self.config = config or CellConfig()
        self.robot = default_robot()
        self.monitor = SafetyMonitor(self.robot, self.config.ssm)
        self.collision = CollisionModel(self.robot, scene or Scene(floor_z=0.0), self.config.ssm.min_separation)
        # the planning layer as the cell configures it (its planning section: patience, gains, posture, judge, horizon)
        options = ReplanOptions(**self.config.planning.replan_fields())
        self.replanner = Replanner(self.collision, JointPlanner(self.collision, PlannerOptions(seed=planner_seed)),
                                   self.config.ssm, options=options, forecaster=forecaster, scaling=self.config.scaling)
        # the same planning layer, its forecast the script's own future (set per run) over a longer horizon
        self.foreseeing = Replanner(self.collision, self.replanner.planner, self.config.ssm,
                                    options=foresight_options(options), scaling=self.config.scaling)
        self.oracle = Replanner(self.collision, self.replanner.planner, self.config.ssm,
                                options=oracle_options(options, times=oracle_search, judge=oracle_judge),
                                scaling=self.config.scaling)
        self.paper_ssm = self.config.ssm.paper_formula()
        self.paper_replanner = Replanner(self.collision, self.replanner.planner, self.paper_ssm, options=options,
                                         forecaster=forecaster, scaling=self.config.scaling)
        lim = self.robot.limits
        shuttle = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration)
        s = np.linspace(0.0, shuttle.duration, 200)
        q, dq, _ = shuttle.sample(s)
        self.robot_speed = max(fastest_point_speed(self.robot, q[k], dq[k]) for k in range(s.size))
        self.zones = SpeedZones.sized(self.config.ssm, self.robot_speed)     # latency 0; zones_at for another
        self.fixed_path = FixedPath(self.collision)
        self.shaped = ShapedLegs(self.collision)
        self.usable_shapes = [k for k in range(len(self.shaped.shapes)) if self.shaped.usable(k, (Q_START, Q_GOAL))]

    def run(self, strategy: str, kind: str, seed: int, duration: float, veto: Veto | None = None,
            goal_leg: GoalLeg | None = None, latency: float = 0.0) -> SimResult:
        """One strategy on one seeded scenario. veto, goal_leg: the planning layer's replans to drop and new goals'
        legs to replace (``run_shuttle``'s; full and full_paper). latency (s): the people reach the cell that long
        after their capture (``run_shuttle``'s)."""
        return self._run(strategy, make_scenario(kind, seed, duration), duration, veto, goal_leg, latency)

    def zones_at(self, latency: float) -> SpeedZones:
        """The zones an integrator sizes for a sensor whose data is `latency` s late (s)."""
        return self.zones if latency == 0.0 else SpeedZones.sized(self.config.ssm, self.robot_speed, latency=latency)

    def clairvoyant(self, kind: str, seed: int, duration: float,
                    sizes: tuple[int, ...] = SEARCHES, latency: float = 0.0) -> tuple[dict[int, Choice], int]:
        """The clairvoyant bound's nested searches on one seeded scenario (``evidence.clairvoyant``): ({number
        of shapes: the best sequence found}, the runs it took)."""
        return self._clairvoyant(make_scenario(kind, seed, duration), duration, sizes, latency)

    def greedy(self, kind: str, seed: int, duration: float) -> tuple[Choice, int]:
        """The clairvoyant chooser one leg ahead on one seeded scenario (``evidence.clairvoyant.greedy_sequence``,
        every usable shape): (its sequence, the runs it took)."""
        runs = self._episode(make_scenario(kind, seed, duration), duration)
        return greedy_sequence(runs, self.usable_shapes), runs.runs

    def _clairvoyant(self, human, duration: float, sizes: tuple[int, ...],
                     latency: float = 0.0) -> tuple[dict[int, Choice], int]:
        runs = self._episode(human, duration, latency)
        return nested_searches(runs, self.usable_shapes, sizes), runs.runs

    def _episode(self, human, duration: float, latency: float = 0.0) -> EpisodeRuns:
        """The runs of sequences of leg shapes with these people (each sequence run once)."""
        return EpisodeRuns(lambda legs: self.shaped_run(human, duration, legs, latency), self.shaped)

    def shaped_run(self, human, duration: float, legs: LegSequence, latency: float = 0.0) -> SimResult:
        """The scaling layer alone, each leg the shape the sequence names."""
        layer = ScalingLayer(self.robot, self.config.ssm, self.config.scaling)
        return self._shuttle(human, duration, latency, layer=layer, leg_path=legs)

    def empty_cell(self, duration: float) -> SimResult:
        """The shuttle with nobody in the cell for `duration` s (the scaling layer, at full speed): what the
        people cost a strategy is measured against it (bench/compare.py: the share of it won back)."""
        return self._run("scale_only", EmptyCell(), duration)

    def _shuttle(self, people, duration: float, latency: float, **how) -> SimResult:
        """``run_shuttle`` between the shuttle's ends with these people, judged by the monitor, the people `latency`
        s late; `how`: what the strategy runs (its layer, planner, leg paths, ...)."""
        return run_shuttle(self.robot, self.config, people, Q_START, Q_GOAL, duration, monitor=self.monitor,
                           latency=latency, **how)

    def _run(self, strategy: str, human, duration: float, veto: Veto | None = None,
             goal_leg: GoalLeg | None = None, latency: float = 0.0) -> SimResult:
        """One strategy with these people (anything with ``at(t)`` and ``phase(t)``, as run_shuttle takes);
        veto, goal_leg and latency as in ``run``."""
        cfg = self.config
        if strategy == "zones":
            layer = ZoneScalingLayer(self.robot, self.zones_at(latency), cfg.ssm, cfg.scaling)
            return self._shuttle(human, duration, latency, layer=layer)
        if strategy == "scale_only":
            return self._shuttle(human, duration, latency, layer=ScalingLayer(self.robot, cfg.ssm, cfg.scaling))
        if strategy == "fixed_path":
            layer = ScalingLayer(self.robot, cfg.ssm, cfg.scaling)
            return self._shuttle(human, duration, latency, layer=layer, leg_path=self.fixed_path.leg)
        if strategy == "full":
            return self._shuttle(human, duration, latency, replanner=self.replanner, charge_planning=CELL_BUDGET,
                                 veto=veto, goal_leg=goal_leg)
        if strategy == "clairvoyant":           # the largest search's sequence, run once more for its record
            best = self._clairvoyant(human, duration, SEARCHES, latency)[0][max(SEARCHES)]
            return self.shaped_run(human, duration, LegSequence(self.shaped, best.shapes), latency)
        if strategy in BOUNDS:
            foreseen = Foresight(human)
            planner = self.foreseeing if strategy == "foresight" else self.oracle
            planner.cost.forecaster = foreseen
            # the oracle plans free of time: its plans are taken the cycle they are asked for
            return self._shuttle(foreseen, duration, latency, replanner=planner,
                                 charge_planning=CELL_BUDGET if strategy == "foresight" else False)
        if strategy in PAPER + PAPER_BASELINES:
            layer = ScalingLayer(self.robot, self.paper_ssm, cfg.scaling)
            replanner = self.paper_replanner if strategy == "full_paper" else None
            return self._shuttle(human, duration, latency, layer=layer, replanner=replanner,
                                 charge_planning=CELL_BUDGET if replanner is not None else False,
                                 leg_path=self.fixed_path.leg if strategy in PAPER_BASELINES else None, veto=veto,
                                 goal_leg=goal_leg)
        raise ValueError(f"unknown strategy {strategy!r}; known: {KNOWN}")
