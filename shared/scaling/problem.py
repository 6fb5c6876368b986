"""The scaling problem of one control cycle: the largest safe path speed, and two solvers for it.

The robot follows the planned path exactly: q(s), joint velocity q'(s) sdot, with sdot = alpha sdot_nom.
Each cycle the largest alpha in [0, 1] is sought such that

* SSM (hard): for every robot link i and human capsule j, the speed at which link i approaches capsule j,
  n_ij^T J_i(q) q'(s) sdot_nom alpha, stays below max(v_r_max,ij - tracking_margin, 0), v_r_max taken at the
  stopping time of that alpha (``shared.safety.ssm.speed_alpha_bound``, the one bound all SSM rows give; the margin covers
  the measured lag of the drives behind their setpoints, ``SsmParameters.tracking_margin``). The approach speed of a rigid
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

from shared.core.humans import HumanCapsules
from shared.robot.model import RobotModel, chain_points_and_velocities
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import NEGLIGIBLE_SPEED, PairSsm, _limits_each, _pair_ssm_kernel, speed_alpha_bound, stop_of_speed


@dataclass(slots=True)
class ScalingRows:
    """One cycle's problem, all rows in terms of alpha.

    Hard rows c alpha <= b: joint velocity, |q'_j sdot_nom| alpha <= v_max_j, and one SSM row per link x
    human capsule pair, robot_speed alpha <= max(limit, 0). Every bound is >= 0, so alpha = 0 is always
    feasible. With one decision variable each hard row says alpha <= b / c, so the tightest implies all
    others: ``upper`` (exact) is all the solvers need of them (an exact presolve; the tests check the
    solutions against every row, ``hard_coef`` / ``hard_bound``).
    Soft rows soft_coef alpha - sigma <= soft_bound: acceleration limits normalised by the limit, without
    the rows that hold for every alpha (coefficient 0, bound >= 0).
    ssm: per-pair SSM quantities at alpha = 1 (the limit at the full-speed T_s), or None when no human capsule
    is present. state: the same with each limit at the stopping time of alpha = upper (every alpha up to upper
    keeps its rows within these: a slower robot stops sooner), or None.
    upper_free: every soft row holds at alpha = upper without slack (the exact presolve of ``solve``).
    """

    joint_speed: np.ndarray
    joint_speed_limit: np.ndarray
    upper: float
    soft_coef: np.ndarray
    soft_bound: np.ndarray
    ssm: PairSsm | None
    tracking_margin: float = 0.0
    upper_free: bool = False
    state: PairSsm | None = None

    @property
    def hard_coef(self) -> np.ndarray:
        ssm = self.ssm.robot_speed.ravel() if self.ssm is not None else np.zeros(0)
        return np.concatenate([self.joint_speed, ssm])

    @property
    def hard_bound(self) -> np.ndarray:
        ssm = np.maximum(self.state.limit - self.tracking_margin, 0.0).ravel() if self.state is not None else np.zeros(0)
        return np.concatenate([self.joint_speed_limit, ssm])

    def slack(self, alpha: float) -> float:
        """sigma(alpha) = max(0, max_r soft_coef_r alpha - soft_bound_r): the least slack alpha needs."""
        if self.soft_coef.size == 0:
            return 0.0
        return float(max(0.0, np.max(self.soft_coef * alpha - self.soft_bound)))


@numba.njit(cache=True)
def _joint_bound(joint_speed, joint_speed_limit):
    """min(1, v_max_j / |q'_j| over the joints that move): the largest alpha the velocity rows allow."""
    upper = 1.0
    for j in range(joint_speed.shape[0]):
        if joint_speed[j] > NEGLIGIBLE_SPEED:
            upper = min(upper, joint_speed_limit[j] / joint_speed[j])
    return upper


@numba.njit(cache=True)
def speed_fraction(joint_velocity, joint_speed_limit):
    """The fastest joint's |velocity| as a fraction of its limit: what a state's T_s scales with."""
    fraction = 0.0
    for j in range(joint_velocity.shape[0]):
        fraction = max(fraction, abs(joint_velocity[j]) / joint_speed_limit[j])
    return fraction


@numba.njit(cache=True)
def _state_limits(dist, human_speed, stop, reaction, a_stop, static, near_d, v_near, v_far, a_h, lead):
    """Every pair's limit at the stopping time `stop` (s), shaped like dist."""
    flat_d = dist.copy().reshape(-1)
    out = _limits_each(flat_d, human_speed.copy().reshape(-1), np.full(flat_d.shape[0], stop), reaction, a_stop,
                       static, near_d, v_near, v_far, a_h, lead)
    return out.reshape(dist.shape)


@numba.njit(cache=True)
def _acceleration_rows(dq, d2q, sdot_nominal, sdot_prev, period, acceleration):
    """qdd(alpha) ~= d2q (2 sdot_prev sdot - sdot_prev^2) + dq (sdot - sdot_prev) / T with sdot = alpha
    sdot_nom (sdot^2 linearised at sdot_prev), written as g alpha + h and bounded by +-a_max: rows
    (g / a) alpha - sigma <= 1 - h / a and (-g / a) alpha - sigma <= 1 + h / a, the always-true ones left out."""
    n = dq.shape[0]
    coef = np.empty(2 * n)
    bound = np.empty(2 * n)
    m = 0
    for j in range(n):
        g = (2.0 * d2q[j] * sdot_prev + dq[j] / period) * sdot_nominal / acceleration[j]
        h = (-d2q[j] * sdot_prev * sdot_prev - dq[j] * sdot_prev / period) / acceleration[j]
        for sign in (1.0, -1.0):
            c, b = sign * g, 1.0 - sign * h
            if c != 0.0 or b < 0.0:
                coef[m], bound[m] = c, b
                m += 1
    return coef[:m], bound[:m]


@numba.njit(cache=True)
def _cycle_rows(q, dq, d2q, sdot_nominal, sdot_prev, period, velocity, acceleration, placement, parent, local,
                joint, ancestry, radii, human_seg, human_rad, human_vel, human_known, horizon, fixed, near_d,
                v_near, v_far, a_h, lead, stop_full, stop_min, reaction, a_stop, static, margin):
    """``build_rows`` in one compiled call: the joint speeds at alpha = 1, every pair's SSM row (kinematics and
    ``_pair_ssm_kernel``; empty without people), the hard rows' bound, each pair's limit at that bound's stopping
    time, the acceleration rows and whether they all hold at that bound (one call: each compiled call costs its
    arguments' unboxing)."""
    n_links = radii.shape[0]
    tangent = dq * sdot_nominal                                        # joint velocity at alpha = 1
    joint_speed = np.abs(tangent)
    if human_seg.shape[0]:
        points, vel = chain_points_and_velocities(q, tangent, placement, parent, local, joint, ancestry)
        dist, robot_speed, human_speed, limit = _pair_ssm_kernel(
            points.reshape(n_links, 2, 3), radii, vel.reshape(n_links, 2, 3), human_seg, human_rad, human_vel,
            human_known, horizon, fixed, near_d, v_near, v_far, a_h, lead)
    else:
        dist = robot_speed = human_speed = limit = np.zeros((n_links, 0))
    fraction = speed_fraction(tangent, velocity)
    upper = min(_joint_bound(joint_speed, velocity),
                speed_alpha_bound(dist, robot_speed, human_speed, limit, fraction, stop_full, stop_min, reaction,
                                  a_stop, static, near_d, v_near, v_far, a_h, lead, margin))
    if stop_min < stop_full:
        state = _state_limits(dist, human_speed, stop_of_speed(upper, fraction, stop_full, stop_min), reaction,
                              a_stop, static, near_d, v_near, v_far, a_h, lead)
    else:
        state = limit
    coef, bound = _acceleration_rows(dq, d2q, sdot_nominal, sdot_prev, period, acceleration)
    upper_free = True
    for r in range(coef.shape[0]):
        upper_free = upper_free and coef[r] * upper <= bound[r]
    return joint_speed, dist, robot_speed, human_speed, limit, state, upper, coef, bound, upper_free


def build_rows(robot: RobotModel, q: np.ndarray, dq_ds: np.ndarray, d2q_ds2: np.ndarray, sdot_nominal: float,
               sdot_prev: float, humans: HumanCapsules, ssm: SsmParameters, period: float) -> ScalingRows:
    """Assemble one cycle's problem at configuration q for the path tangent dq_ds (pure, no I/O)."""
    lim = robot.limits
    joint_speed, dist, robot_speed, human_speed, limit, state, upper, coef, bound, upper_free = _cycle_rows(
        np.asarray(q, dtype=np.float64), np.asarray(dq_ds, dtype=np.float64), np.asarray(d2q_ds2, dtype=np.float64),
        float(sdot_nominal), float(sdot_prev), float(period), lim.velocity, lim.acceleration, *robot.chain,
        robot.ancestry, robot.radii, humans.segments, humans.radii, humans.velocities, humans.velocity_known,
        *ssm.kernel_constants, *ssm.stop_constants, ssm.tracking_margin)
    pairs = PairSsm(dist, robot_speed, human_speed, limit) if humans.count else None
    at_stop = PairSsm(dist, robot_speed, human_speed, state) if humans.count else None
    return ScalingRows(joint_speed, lim.velocity, upper, coef, bound, pairs, ssm.tracking_margin, upper_free, at_stop)


def ssm_alpha_bound(robot: RobotModel, q: np.ndarray, joint_velocity: np.ndarray, humans: HumanCapsules,
                    ssm: SsmParameters) -> float:
    """The largest alpha in [0, 1] for which moving at alpha * joint_velocity from q meets every SSM row."""
    if not humans.count:
        return 1.0
    return motion_alpha_bound(np.asarray(q, dtype=np.float64), np.asarray(joint_velocity, dtype=np.float64),
                              robot.limits.velocity, *robot.chain, robot.ancestry, robot.radii, humans.segments,
                              humans.radii, humans.velocities, humans.velocity_known, *ssm.kernel_constants,
                              *ssm.stop_constants, ssm.tracking_margin)


@numba.njit(cache=True)
def motion_alpha_bound(q, joint_velocity, velocity_limit, placement, parent, local, joint, ancestry, radii,
                       human_seg, human_rad, human_vel, human_known, horizon, fixed, near_d, v_near, v_far, a_h, lead,
                       stop_full, stop_min, reaction, a_stop, static, margin):
    """``ssm_alpha_bound`` in one compiled call (the kinematics, every pair's SSM row, their bound at the stopping
    time of each alpha, ``speed_alpha_bound``; the kernels the scaling rows and the planning layer's time cost use):
    the scaling layer checks every command with it, without the Python between three calls that a control cycle
    pays for on cold caches."""
    n_links = radii.shape[0]
    points, velocities = chain_points_and_velocities(q, joint_velocity, placement, parent, local, joint, ancestry)
    dist, robot_speed, human_speed, limit = _pair_ssm_kernel(
        points.reshape(n_links, 2, 3), radii, velocities.reshape(n_links, 2, 3), human_seg, human_rad, human_vel,
        human_known, horizon, fixed, near_d, v_near, v_far, a_h, lead)
    return speed_alpha_bound(dist, robot_speed, human_speed, limit, speed_fraction(joint_velocity, velocity_limit),
                             stop_full, stop_min, reaction, a_stop, static, near_d, v_near, v_far, a_h, lead, margin)


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

    The hard part enters as the bound alpha <= upper (see ``ScalingRows``), so a problem has between 0
    and 2 dof soft rows whatever the number of humans. piqp's time grows with the row count, so there is
    one solver per row count, each set up once on first use and only updated after that: no padding.
    """

    def __init__(self, weight: float, dof: int = 6) -> None:
        self.weight = float(weight)
        self.max_rows = 2 * dof
        self._pool: dict[int, tuple[piqp.DenseSolver, np.ndarray, np.ndarray, np.ndarray]] = {}
        self.last_status = None
        self.last_iterations = 0

    def _solver(self, rows: int) -> tuple[piqp.DenseSolver, np.ndarray, np.ndarray, np.ndarray]:
        entry = self._pool.get(rows)
        if entry is None:
            if rows > self.max_rows:
                raise ValueError(f"{rows} soft rows do not fit a solver for {self.max_rows}")
            G = np.zeros((rows, 2), order="F")
            G[:, 1] = -1.0
            h = np.ones(rows)
            x_u = np.array([1.0, np.inf])
            solver = piqp.DenseSolver()
            solver.settings.verbose = False
            if rows:
                solver.setup(np.zeros((2, 2), order="F"), np.array([-1.0, self.weight]), G=G, h_u=h,
                             x_l=np.zeros(2), x_u=x_u)
            else:
                solver.setup(np.zeros((2, 2), order="F"), np.array([-1.0, self.weight]), x_l=np.zeros(2), x_u=x_u)
            entry = self._pool[rows] = (solver, G, h, x_u)
        return entry

    def solve(self, rows: ScalingRows) -> float | None:
        """alpha from piqp, or None when piqp did not report an optimal solution."""
        n = rows.soft_coef.size
        solver, G, h, x_u = self._solver(n)
        x_u[0] = rows.upper
        if n:
            G[:, 0] = rows.soft_coef
            h[:] = rows.soft_bound
            solver.update(G=G, h_u=h, x_u=x_u)
        else:
            solver.update(x_u=x_u)
        status = solver.solve()
        self.last_status = status
        if status != piqp.PIQP_SOLVED:
            return None
        return float(solver.result.x[0])


@dataclass(slots=True)
class Solution:
    """alpha and how it was found: 'presolved' (no acceleration row binds: upper is the optimum), 'piqp',
    'closed_form', or 'closed_form_fallback' after a piqp failure."""

    alpha: float
    method: str


def solve(rows: ScalingRows, weight: float, piqp_solver: PiqpScalingSolver | None) -> Solution:
    """Solve one cycle: piqp when given (the closed form if piqp fails), else the closed form.

    First an exact presolve, like the hard rows' (``ScalingRows.upper``): when every acceleration row holds
    at alpha = upper with no slack, that point is the optimum (the objective wants alpha as large and the
    slack as small as they can be, and both are at their bound), and no solver is needed. That is most
    cycles: cruising at full speed or at the SSM's bound. A solver runs when the acceleration limits
    bind (ramping up, or slowing down faster than the drives allow and paying slack for it): piqp's time,
    twice the rest of the cycle's, is then spent where the problem needs it. The result is clipped to
    [0, upper], so every hard (safety and velocity) row holds exactly whatever the solver's tolerance.
    """
    if rows.upper_free:
        return Solution(rows.upper, "presolved")
    method = "closed_form"
    alpha = None
    if piqp_solver is not None:
        alpha = piqp_solver.solve(rows)
        method = "piqp" if alpha is not None else "closed_form_fallback"
    if alpha is None:
        alpha = solve_closed_form(rows, weight)
    alpha = min(max(alpha, 0.0), rows.upper)
    return Solution(alpha, method)
