"""The scaling problem of one control cycle: the largest safe path speed, and two solvers for it.

The robot follows the planned path exactly: q(s), joint velocity q'(s) sdot, with sdot = alpha sdot_nom.
Each cycle the largest alpha in [0, 1] is sought such that

* SSM (hard): for every robot link i and human capsule j, the speed at which link i approaches capsule j,
  n_ij^T J_i(q) q'(s) sdot_nom alpha, stays below max(v_r_max,ij, 0). The approach speed of a rigid
  segment is affine along it, so the largest of its two end points' speeds is used with the pair's
  closest distance: conservative for the whole link, not only for the closest point. A negative limit
  forbids approaching but never forbids moving away. Where the two axes touch (no direction defined)
  the full speed of the link counts as approach.
* joint velocity (hard): |q'_j sdot_nom alpha| <= v_max_j.
* joint acceleration (soft): q''_j sdot^2 + q'_j (sdot - sdot_prev)/T within +-a_max_j, with sdot^2
  linearised at sdot_prev; one slack sigma >= 0, in units of the limit, is paid for with weight w.

The problem  min -alpha + w sigma  s.t. the rows above, 0 <= alpha <= 1, sigma >= 0  is an LP in two
variables that is always feasible (alpha = 0 with enough slack) and in which safety always wins.

``PiqpScalingSolver`` solves it with piqp's dense interior-point solver, set up once and updated every
cycle. ``solve_closed_form`` solves the very same problem exactly by enumeration (the objective is convex
and piecewise linear in alpha, so its minimum lies at a kink or an end). Both results are projected onto
the hard constraints, so no solver tolerance can ever exceed the safety limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import piqp

from shared.humans import HumanCapsules
from shared.robot_model import RobotModel
from shared.ssm import PairSsm, SsmParameters, pair_ssm


@dataclass(frozen=True)
class ScalingRows:
    """One cycle's problem, all rows in terms of alpha.

    hard_coef * alpha <= hard_bound: the joint velocity rows, then the SSM rows (one per link x human
    capsule pair); every bound is >= 0, so alpha = 0 is always feasible.
    upper: the largest alpha in [0, 1] that every hard row allows (exact). With one decision variable,
    every hard row c alpha <= b (c > 0) says alpha <= b / c, so the tightest row implies all others:
    the solvers get the hard part as this single bound (an exact presolve; the tests check the result
    against every row).
    soft_coef * alpha - sigma <= soft_bound: acceleration rows normalised by the limit, without the rows
    that hold for every alpha (coefficient 0, bound >= 0).
    ssm: per-pair SSM quantities at alpha = 1, or None when no human capsule is present.
    """

    hard_coef: np.ndarray
    hard_bound: np.ndarray
    upper: float
    soft_coef: np.ndarray
    soft_bound: np.ndarray
    ssm: PairSsm | None

    def slack(self, alpha: float) -> float:
        """sigma(alpha) = max(0, max_r soft_coef_r alpha - soft_bound_r): the least slack alpha needs."""
        if self.soft_coef.size == 0:
            return 0.0
        return float(max(0.0, np.max(self.soft_coef * alpha - self.soft_bound)))


_NEGLIGIBLE_SPEED = 1e-12   # m/s: a row coefficient below this counts as zero (no overflow in b / c)


def _hard_upper(coef: np.ndarray, bound: np.ndarray) -> float:
    """min(1, min over rows with c > 0 of b / c): the largest alpha every hard row allows."""
    ratio = np.divide(bound, coef, out=np.full(coef.shape, np.inf), where=coef > _NEGLIGIBLE_SPEED)
    return float(min(1.0, ratio.min())) if ratio.size else 1.0


def build_rows(robot: RobotModel, q: np.ndarray, dq_ds: np.ndarray, d2q_ds2: np.ndarray, sdot_nominal: float,
               sdot_prev: float, humans: HumanCapsules, ssm: SsmParameters, period: float) -> ScalingRows:
    """Assemble one cycle's problem at configuration q for the path tangent dq_ds (pure, no I/O)."""
    dq = np.asarray(dq_ds, dtype=float)
    d2q = np.asarray(d2q_ds2, dtype=float)
    tangent = dq * sdot_nominal                                        # joint velocity at alpha = 1
    lim = robot.limits
    pairs = None
    hard_coef, hard_bound = np.abs(tangent), lim.velocity
    if humans.count:
        points, jac = robot.capsule_kinematics(q)                       # (L,2,3), (L,2,3,6)
        pairs = pair_ssm(points, robot.radii, jac @ tangent, humans, ssm)
        hard_coef = np.concatenate([hard_coef, pairs.robot_speed.ravel()])
        hard_bound = np.concatenate([hard_bound, np.maximum(pairs.limit, 0.0).ravel()])
    # qdd(alpha) ~= d2q (2 sdot_prev sdot - sdot_prev^2) + dq (sdot - sdot_prev) / T, sdot = alpha sdot_nom
    g = (2.0 * d2q * sdot_prev + dq / period) * sdot_nominal / lim.acceleration
    h = (-d2q * sdot_prev ** 2 - dq * sdot_prev / period) / lim.acceleration
    soft_coef = np.concatenate([g, -g])
    soft_bound = np.concatenate([1.0 - h, 1.0 + h])
    keep = (soft_coef != 0.0) | (soft_bound < 0.0)
    return ScalingRows(hard_coef, hard_bound, _hard_upper(hard_coef, hard_bound), soft_coef[keep],
                       soft_bound[keep], pairs)


def ssm_alpha_bound(robot: RobotModel, q: np.ndarray, joint_velocity: np.ndarray, humans: HumanCapsules,
                    ssm: SsmParameters) -> float:
    """The largest alpha in [0, 1] for which moving at alpha * joint_velocity from q meets every SSM row."""
    if not humans.count:
        return 1.0
    points, jac = robot.capsule_kinematics(q)
    pairs = pair_ssm(points, robot.radii, jac @ joint_velocity, humans, ssm)
    return _hard_upper(pairs.robot_speed.ravel(), np.maximum(pairs.limit, 0.0).ravel())


@numba.njit(cache=True)
def _closed_form_kernel(upper, g, u, weight):
    # candidates: both ends, every soft row's root, every crossing of two soft rows
    best_alpha, best_cost = 0.0, np.inf
    n = g.shape[0]
    for c in range(2 + n + n * n):
        if c == 0:
            a = 0.0
        elif c == 1:
            a = upper
        elif c < 2 + n:
            r = c - 2
            if g[r] == 0.0:
                continue
            a = u[r] / g[r]
        else:
            r, s = divmod(c - 2 - n, n)
            if s <= r or g[r] == g[s]:
                continue
            a = (u[r] - u[s]) / (g[r] - g[s])
        a = min(max(a, 0.0), upper)
        sigma = 0.0
        for r in range(n):
            sigma = max(sigma, g[r] * a - u[r])
        cost = -a + weight * sigma
        tol = 1e-12 * max(1.0, abs(best_cost)) if best_cost != np.inf else 0.0
        if cost < best_cost - tol or (abs(cost - best_cost) <= tol and a > best_alpha):
            best_alpha, best_cost = a, cost
    return best_alpha


def solve_closed_form(rows: ScalingRows, weight: float) -> float:
    """Exact alpha of  min -alpha + w sigma(alpha)  over the hard interval [0, upper].

    sigma is the maximum of affine functions and zero, so the objective is convex and piecewise linear and
    its minimum is at an end of the interval or at a kink: a root of a soft row or the crossing of two.
    Every candidate is evaluated; among equal objectives the largest alpha wins.
    """
    return float(_closed_form_kernel(rows.upper, rows.soft_coef, rows.soft_bound, float(weight)))


class PiqpScalingSolver:
    """The scaling LP  min -alpha + w sigma  in piqp's dense solver, x = (alpha, sigma).

    Set up once and updated every cycle. The hard part enters as the bound alpha <= upper (see
    ``ScalingRows``), so the problem has at most 2 dof soft rows whatever the number of humans; unused
    rows are padded with 0 <= 1.
    """

    def __init__(self, weight: float, dof: int = 6) -> None:
        self.weight = float(weight)
        self._G = np.zeros((2 * dof, 2), order="F")
        self._G[:, 1] = -1.0
        self._h = np.ones(2 * dof)
        self._xu = np.array([1.0, np.inf])
        self._solver = piqp.DenseSolver()
        self._solver.settings.verbose = False
        self._solver.setup(np.zeros((2, 2), order="F"), np.array([-1.0, self.weight]), G=self._G, h_u=self._h,
                           x_l=np.zeros(2), x_u=self._xu)
        self.last_status = "none"
        self.last_iterations = 0

    def solve(self, rows: ScalingRows) -> float | None:
        """alpha from piqp, or None when piqp did not report an optimal solution."""
        n = rows.soft_coef.size
        if n > self._h.size:
            raise ValueError(f"{n} soft rows do not fit a solver set up for {self._h.size}")
        self._G[:, 0] = 0.0
        self._G[:n, 0] = rows.soft_coef
        self._h[:] = 1.0
        self._h[:n] = rows.soft_bound
        self._xu[0] = rows.upper
        self._solver.update(G=self._G, h_u=self._h, x_u=self._xu)
        status = self._solver.solve()
        self.last_status = status.name
        self.last_iterations = int(self._solver.result.info.iter)
        if status != piqp.PIQP_SOLVED:
            return None
        return float(self._solver.result.x[0])


@dataclass(frozen=True)
class Solution:
    """alpha and how it was found: 'piqp', 'closed_form', or 'closed_form_fallback' after a piqp failure."""

    alpha: float
    method: str
    slack: float


def solve(rows: ScalingRows, weight: float, piqp_solver: PiqpScalingSolver | None) -> Solution:
    """Solve one cycle: piqp when given (the closed form if piqp fails), else the closed form.

    The result is clipped to [0, upper], so every hard (safety and velocity) row holds exactly whatever
    the solver's tolerance.
    """
    method = "closed_form"
    alpha = None
    if piqp_solver is not None:
        alpha = piqp_solver.solve(rows)
        method = "piqp" if alpha is not None else "closed_form_fallback"
    if alpha is None:
        alpha = solve_closed_form(rows, weight)
    alpha = min(max(alpha, 0.0), rows.upper)
    return Solution(alpha, method, rows.slack(alpha))
