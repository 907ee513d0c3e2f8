"""Inverse kinematics of a fixed target pose: a sequential box QP with restarts from a seed bank.

Each step linearizes the SE(3) error of the gripper frame and solves, for the joint step ``dq``,

    min_dq  ½ ‖J_e dq + e‖² + ½ λ ‖dq‖²    s.t.  q_lo − q ≤ dq ≤ q_hi − q

where ``e = log(T(q)⁻¹ T*)`` is the error twist in the gripper frame, ``J_e = −Jlog(e) J(q)`` its
Jacobian (Pinocchio's frame Jacobian in the gripper frame, through the derivative of the SE(3)
log) and ``λ = (λ₀ + μ‖e‖²) β`` a Levenberg–Marquardt damping that vanishes at the solution.
When the unconstrained minimizer lies inside the joint limits it *is* the QP's solution and is
taken in closed form; otherwise the box QP is solved exactly by an active-set iteration, or by
OSQP when that does not settle (:mod:`grace_dsl.robot.qp`). A step longer than the trust region
``δ`` (on any joint) is scaled down to it, keeping its direction. A step that does not lower
``‖e‖²`` is refused and ``β`` raised tenfold (an accepted one divides it by 3, down to 1). An
attempt that stalls restarts from the next configuration of the robot's seed bank whose gripper
lies nearest the target (:mod:`grace_dsl.robot.seeds`), then from seeded random ones.

The effort is counted, not timed: ``max_restarts`` attempts of at most ``max_iterations`` steps
each, so a result is a function of the target, the start and the seed alone, whatever the
machine's load. ``time_limit`` (off by default) is only a safety cap: when it ends a search the
reason says ``time_limit``, a failure that depends on the load and is reported as such.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import pinocchio as pin

from grace_dsl.robot.model import Robot, rigid_pose
from grace_dsl.robot.qp import BoxQP, active_set, spd_solve
from grace_dsl.robot.seeds import seed_bank

FloatArray = np.ndarray

POSITION_TOLERANCE = 1e-3  # metres
ROTATION_TOLERANCE = math.radians(1.0)
BOOST_UP, BOOST_DOWN = 10.0, 3.0  # LM damping after a refused / an accepted step
REASONS = ("converged", "unreachable", "time_limit")


@dataclass(frozen=True)
class IKResult:
    """The outcome of :func:`solve_ik`; ``q`` is the best configuration found either way.

    ``success`` holds only when the forward kinematics of ``q`` lies within the tolerances of the
    target: ``error_pos`` (metres) and ``error_rot`` (radians) are measured on it, not estimated.
    """

    success: bool
    q: FloatArray
    pose: FloatArray
    error_pos: float
    error_rot: float
    iterations: int
    restarts: int
    seconds: float
    reason: str


@dataclass(frozen=True)
class IKOptions:
    """Tolerances and effort limits of :func:`solve_ik` (SI units)."""

    tol_pos: float = POSITION_TOLERANCE
    tol_rot: float = ROTATION_TOLERANCE
    max_iterations: int = 30  # per attempt
    stall_window: int = 5  # steps without 5% progress that end an attempt
    max_restarts: int = 40  # the search's budget: attempts after the first, a count
    time_limit: float | None = None  # optional wall-clock safety cap (s); off: load-independent
    trust_region: float = 0.4  # radians per joint per step
    damping: float = 1e-6  # λ₀
    damping_error: float = 1e-2  # μ
    bank_seeds: int = 8  # restarts from the seed bank's nearest entries before random ones


def solve_ik(
    robot: Robot,
    target: Any,
    q0: Any = None,
    *,
    seed: int = 0,
    options: IKOptions | None = None,
) -> IKResult:
    """Joint values that put ``robot``'s gripper frame at the 4x4 world pose ``target``.

    Starts from ``q0``, by default from the seed bank's configuration whose gripper lies nearest
    the target; when an attempt stalls it restarts from the bank's next nearest ones
    (``options.bank_seeds``), then from random configurations drawn with ``seed``. Never raises
    for an unreachable target: the result says ``success=False`` with the reason and the closest
    configuration found.
    """
    opts = options or IKOptions()
    goal = pin.SE3(rigid_pose(target, "the IK target"))
    start = time.perf_counter()
    near = list(seed_bank(robot).nearest(goal.homogeneous, opts.bank_seeds + 1))
    q = near.pop(0).copy() if q0 is None else robot.check_q(q0).copy()
    rng: list[np.random.Generator] = []  # drawn from only once the bank's seeds are spent

    def restart() -> FloatArray:
        if near:
            return near.pop(0).copy()
        if not rng:
            rng.append(np.random.default_rng(seed))
        return robot.random_q(rng[0])

    problem = _PoseProblem(robot, goal, opts)
    found = search(problem, q, opts, thread_qp(robot, robot.nq), restart)
    return _result(robot, goal, found, start, opts)


@dataclass(frozen=True)
class Search:
    """The best ``x`` of a restarted descent, its effort and why it stopped: ``converged``,
    ``time_limit``, ``unreachable`` or (with ``usable``) ``collision``."""

    x: FloatArray
    iterations: int
    restarts: int
    reason: str


def search(
    problem: Linearized,
    x: FloatArray,
    opts: IKOptions,
    qp: BoxQP,
    restart: Callable[[], FloatArray],
    usable: Callable[[FloatArray], bool] | None = None,
) -> Search:
    """:func:`descend` from ``x``, then from ``restart()`` after every attempt that stalls, until
    an attempt ends within tolerance at a ``usable`` point or the restart budget is spent (or
    the optional wall-clock cap ``opts.time_limit`` is hit, reason ``time_limit``). A point
    within tolerance that is not usable counts as just outside it."""
    start = time.perf_counter()
    best: tuple[float, FloatArray] = (math.inf, x)
    iterations, rejected = 0, False
    for attempt in range(opts.max_restarts + 1):
        x, used, score = descend(problem, x, opts, qp)
        iterations += used
        if score <= 1.0 and usable is not None and not usable(x):
            rejected, score = True, 1.0 + score
        if score < best[0]:
            best = (score, x.copy())
        if score <= 1.0:
            return Search(best[1], iterations, attempt, "converged")
        if opts.time_limit is not None and time.perf_counter() - start > opts.time_limit:
            return Search(best[1], iterations, attempt, "collision" if rejected else "time_limit")
        if attempt < opts.max_restarts:
            x = restart()
    reason = "collision" if rejected else "unreachable"
    return Search(best[1], iterations, opts.max_restarts, reason)


class Linearized(Protocol):
    """A least-squares problem in ``x`` within ``lower``/``upper``: ``linearize(x)`` gives the
    error twist ``e``, its Jacobian ``de/dx`` and a score that is <= 1 within tolerance."""

    lower: FloatArray
    upper: FloatArray

    def linearize(self, x: FloatArray) -> tuple[FloatArray, FloatArray, float]: ...


@dataclass
class _PoseProblem:
    """The gripper frame of ``robot`` onto the fixed pose ``goal``: x = q."""

    robot: Robot
    goal: pin.SE3
    opts: IKOptions

    def __post_init__(self) -> None:
        self.lower, self.upper = self.robot.lower, self.robot.upper
        self.model, self.data = self.robot.model, self.robot.data()

    def linearize(self, x: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        frame = self.robot.tcp_frame
        pin.computeJointJacobians(self.model, self.data, x)  # also the joints' placements
        now = pin.updateFramePlacement(self.model, self.data, frame)
        jac = pin.getFrameJacobian(self.model, self.data, frame, pin.LOCAL)
        diff = now.actInv(self.goal)
        err = pin.log6(diff).vector
        offset, turn = diff.translation, err[3:]  # ‖offset‖: the distance, in any axes
        score = max(
            math.sqrt(offset @ offset) / self.opts.tol_pos,
            math.sqrt(turn @ turn) / self.opts.tol_rot,
        )
        return err, -pin.Jlog6(diff.inverse()) @ jac, score


def descend(
    problem: Linearized, x: FloatArray, opts: IKOptions, qp: BoxQP
) -> tuple[FloatArray, int, float]:
    """Levenberg-Marquardt QP steps from ``x`` until within 1/10 of the tolerance, stalled or out
    of iterations; returns (x, iterations, score). A step that does not lower ``‖e‖²`` is
    refused and the damping raised tenfold; an accepted one lowers it again."""
    lo, hi = problem.lower, problem.upper
    diagonal = np.arange(len(x))
    err, j_err, score = problem.linearize(x)
    if score <= 0.1:
        return x, 0, score
    cost = float(err @ err)
    boost = 1.0
    history = [score]
    for it in range(1, opts.max_iterations + 1):
        p = j_err.T @ j_err
        p[diagonal, diagonal] += (opts.damping + opts.damping_error * cost) * boost
        c = j_err.T @ err
        step = _box_step(p, c, lo - x, hi - x, qp)
        largest = float(np.abs(step).max())
        if largest > opts.trust_region:  # far from the goal the linearization is poor
            step *= opts.trust_region / largest
        trial = np.minimum(np.maximum(x + step, lo), hi)
        t_err, t_jac, t_score = problem.linearize(trial)
        t_cost = float(t_err @ t_err)
        if t_cost < cost:
            x, err, j_err, score, cost = trial, t_err, t_jac, t_score, t_cost
            boost = max(1.0, boost / BOOST_DOWN)
        else:
            boost *= BOOST_UP
        history.append(score)
        if score <= 0.1 or _stalled(history, opts.stall_window):
            return x, it, score
    return x, opts.max_iterations, score


def _box_step(
    p: FloatArray, c: FloatArray, lo: FloatArray, hi: FloatArray, qp: BoxQP
) -> FloatArray:
    """The QP's minimizer: in closed form when it lies inside the box (no limit binds), else by
    the exact active-set iteration, else (its sets did not settle) by OSQP."""
    step = spd_solve(p, -c)
    if step is None:
        return qp.solve(p, c, lo, hi)
    if not ((step < lo).any() or (step > hi).any()):
        return step
    exact = active_set(p, c, lo, hi, step)
    return qp.solve(p, c, lo, hi) if exact is None else exact


def thread_qp(robot: Robot, n: int) -> BoxQP:
    """One OSQP workspace per robot, size and thread: its setup costs far more than a solve."""
    cache = robot._local.__dict__.setdefault("qp", {})
    if n not in cache:
        cache[n] = BoxQP(n)
    return cache[n]


def pose_errors(pose: FloatArray, goal: FloatArray) -> tuple[float, float]:
    """The distance (metres) and the rotation angle (radians) between two 4x4 poses."""
    cos = (np.trace(goal[:3, :3].T @ pose[:3, :3]) - 1.0) / 2.0
    return (
        float(np.linalg.norm(pose[:3, 3] - goal[:3, 3])),
        float(math.acos(min(1.0, max(-1.0, cos)))),
    )


def _stalled(history: list[float], window: int) -> bool:
    """No 5% progress over the last ``window`` steps: the attempt is stuck in a local minimum."""
    if len(history) <= window:
        return False
    return history[-1] > 0.95 * history[-1 - window]


def measure(
    robot: Robot, q: FloatArray, goal: FloatArray, opts: IKOptions
) -> tuple[FloatArray, float, float, bool]:
    """The gripper pose at ``q`` by a fresh forward kinematics (read-only), its distance and
    angle to ``goal``, and whether both are within the tolerances."""
    pose = robot.fk(q)  # measured, not carried over from the iteration
    err_pos, err_rot = pose_errors(pose, goal)
    pose.setflags(write=False)
    return pose, err_pos, err_rot, err_pos <= opts.tol_pos and err_rot <= opts.tol_rot


def _result(robot: Robot, goal: pin.SE3, found: Search, start: float, opts: IKOptions) -> IKResult:
    q = np.array(found.x)
    q.setflags(write=False)
    pose, err_pos, err_rot, success = measure(robot, q, goal.homogeneous, opts)
    reason = "converged" if success else found.reason
    return IKResult(
        success,
        q,
        pose,
        err_pos,
        err_rot,
        found.iterations,
        found.restarts,
        time.perf_counter() - start,
        "unreachable" if reason == "converged" and not success else reason,
    )
