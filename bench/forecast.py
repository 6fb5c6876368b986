"""How well the planning layer's forecast of the people matches what they then do (not a test: it prints figures).

The time cost walks every candidate path against a forecast of the people (``shared.planning.forecast``).
This benchmark holds forecasters against the truth: at every 0.1 s of seeded scenarios (the simulation's
kinds, as bench/compare.py runs them) and of motion files (``--motion``: recorded or scripted people,
docs/human-motion.md), each forecaster's capsules `h` seconds ahead against where the people then are.
The error of a capsule is the larger of its two end points' (m); per kind, horizon and forecaster the
mean and the 95th percentile over capsules and moments (a capsule counted only where it is there both
now and h later). Forecasters:

* still: the people stay where they are (what a planner that ignores velocities assumes);
* constant velocity: the planning layer's default (``ConstantVelocity``, parts slower than
  ``STANDING_SPEED`` held);
* constant velocity, every part: the same with no standing speed (every tracked velocity moved on);
* any other, by name (``--forecaster module:attribute``, ``shared.planning.forecast.load_forecaster``).

Pair it with ``bench/compare.py --foresight`` (the throughput a perfect forecast would give): a new
forecaster plugs into ``SsmTimeCost`` / ``Replanner`` (``forecaster=``), this says how close it gets to the
truth, compare says what that is worth. The last line is one JSON object:
{"errors": {kind: {forecaster: {horizon: [mean, p95]}}}}.

    python bench/forecast.py [--seeds 10] [--duration 12] [--horizons 0.5,1,2] [--motion FILE ...]
                             [--forecaster mypackage.predict:MyForecaster ...]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import SCENARIO_KINDS, kinds_problem, make_scenario  # noqa: E402
from shared.core.errors import ConfigError  # noqa: E402
from shared.planning.forecast import ConstantVelocity, PeopleForecast, load_forecaster  # noqa: E402
from shared.tracking.motion import RecordedMotion  # noqa: E402

STEP = 0.1       # s between the moments a forecast is made


class Still:
    def forecast(self, humans, horizon):
        return PeopleForecast.still(humans)


FORECASTERS = {"still": Still(), "constant velocity": ConstantVelocity(),
               "constant velocity, every part": ConstantVelocity(drift_speed=0.0)}


def capsule_errors(people, duration: float, horizon: float, forecaster) -> np.ndarray:
    """Every capsule's forecast error (m) at `horizon` s, over moments every STEP s of `people` (anything
    with at(t) -> HumanCapsules or None) until `duration` - horizon. A moment counts where the same
    number of capsules is there now and then (a person who appears or leaves in between is not forecast)."""
    out = []
    for t in np.arange(0.0, duration - horizon + 1e-9, STEP):
        now = people.at(float(t))
        if now is None or now.count == 0:
            continue
        ahead = forecaster.forecast(now, horizon).at(horizon)     # made before the future is looked at
        then = people.at(float(t + horizon))
        if then is None or then.count != now.count:
            continue
        out.append(np.linalg.norm(ahead - then.segments, axis=2).max(axis=1))
    return np.concatenate(out) if out else np.zeros(0)


def summarise(errors: np.ndarray) -> list[float] | None:
    """[mean, 95th percentile] in m (None: nothing to forecast)."""
    return None if errors.size == 0 else [round(float(errors.mean()), 4), round(float(np.percentile(errors, 95)), 4)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10, help="seeded scenarios per kind")
    parser.add_argument("--duration", type=float, default=12.0, help="simulated seconds per scenario")
    parser.add_argument("--horizons", default="0.5,1,2", help="comma-separated forecast horizons (s)")
    parser.add_argument("--kinds", default=",".join(sorted(SCENARIO_KINDS)), help="scenario kinds ('' for none)")
    parser.add_argument("--motion", nargs="*", default=[], type=Path, help="motion files, each a kind of its own")
    parser.add_argument("--forecaster", action="append", default=[], metavar="MODULE:ATTRIBUTE",
                        help="another forecaster to hold against the truth (repeatable; shared.planning.forecast)")
    args = parser.parse_args()
    forecasters = dict(FORECASTERS)
    for spec in args.forecaster:
        try:
            forecasters[spec] = load_forecaster(spec)
        except ValueError as exc:
            parser.error(f"--forecaster: {exc}")
    try:
        horizons = [float(h) for h in args.horizons.split(",") if h.strip()]
    except ValueError:
        parser.error(f"--horizons: numbers in seconds, not {args.horizons!r}")
    if not horizons or min(horizons) <= 0 or args.seeds < 0 or args.duration <= 0:
        parser.error("--horizons must be > 0 s, --seeds >= 0, --duration > 0")
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    if problem := kinds_problem(kinds, allow_none=True):
        parser.error(f"--kinds: {problem}")
    sources: dict[str, list[tuple[object, float]]] = {
        k: [(make_scenario(k, seed, args.duration), args.duration) for seed in range(args.seeds)] for k in kinds}
    for path in args.motion:
        try:
            motion = RecordedMotion.load(path)
        except (OSError, ConfigError) as exc:
            parser.error(f"--motion {path}: {exc}")
        sources[path.name] = [(motion, motion.duration)]
    if not any(sources.values()):
        parser.error("nothing to forecast: no --seeds and no --motion")
    result: dict[str, dict] = {}
    print(f"forecast error (m, the larger end of each capsule): mean / 95th percentile, at {horizons} s ahead")
    width = max(len(label) for label in forecasters)
    for name, runs in sources.items():
        result[name] = {}
        for label, forecaster in forecasters.items():
            result[name][label] = {}
            for h in horizons:
                errors = np.concatenate([capsule_errors(p, d, h, forecaster) for p, d in runs])
                result[name][label][str(h)] = summarise(errors)
            print(f"{name:<16} {label:<{width}} " + "  ".join(
                f"{h:g} s: " + ("-" if (e := result[name][label][str(h)]) is None else f"{e[0]:.3f} / {e[1]:.3f}")
                for h in horizons))
    print(json.dumps({"bench": "forecast", "horizons": horizons, "errors": result}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
