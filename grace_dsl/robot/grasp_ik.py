"""Grasp-manifold IK: joint values AND the grasp family's free parameters, in one solve.

A grasp family is a manifold of gripper poses ``G(g)`` over its free parameters ``g`` (where
along a bar, which angle around a knob). Fixing ``g`` first and solving pose IK throws away the
freedom the concept offers; here the unknowns are ``x = (q, g)`` and one sequential QP drives the
gripper frame ``T(q)`` onto ``G(g)``:

    e(x) = log(T(q)⁻¹ G(g)),    ∂e/∂q = −Jlog(e)⁻ J_T(q),    ∂e/∂g = Jlog(e) J_G(g)

with ``J_T`` the robot's frame Jacobian (Pinocchio, gripper frame), ``J_G`` the grasp pose's
Jacobian in its free parameters from the compiler (``grasp_jac:NAME``, exact, native), both as
body twists, ``Jlog`` the derivative of the SE(3) log and ``Jlog(e)⁻`` that of its inverse. The
free parameters are bounded by ``inst.grasp_range`` exactly as the joints by their limits.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from grace_dsl.robot.collision import CollisionScene
from grace_dsl.robot.ik import IKOptions, IKResult, Search, measure, search, thread_qp
from grace_dsl.robot.model import Robot, rigid_pose
from grace_dsl.robot.seeds import seed_bank
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.symmetry import minimal_spin

FloatArray = np.ndarray
FINGERS = ("panda_leftfinger", "panda_rightfinger")


@dataclass(frozen=True)
class GraspIKResult(IKResult):
    """An :class:`IKResult` plus the grasp's chosen free parameters and its world pose."""

    grasp: str
    free: Mapping[str, float]
    grasp_pose: FloatArray
    spin: float = 0.0  # radians about a symmetric grasp's axis (0 for other grasps)


@dataclass
class _GraspProblem:
    """``x = (q, g)``: the robot's joints, then the grasp's free parameters."""

    robot: Robot
    kin: Kinematics
    grasp: str
    base_inv: FloatArray
    opts: IKOptions

    def __post_init__(self) -> None:
        lo, hi, self.default = self.kin.grasp_range(self.grasp)
        self.m = len(lo)
        self.symmetric = self.kin.concept.grasps[self.grasp].symmetric
        if self.symmetric:  # one more unknown: the spin about the symmetry axis
            lo, hi = np.append(lo, -math.pi), np.append(hi, math.pi)
        self.lower = np.concatenate([self.robot.lower, lo])
        self.upper = np.concatenate([self.robot.upper, hi])
        self.n = self.robot.nq
        self.joints = len(self.kin.joints)
        self.model, self.data = self.robot.model, self.robot.data()

    def start(self, q: FloatArray) -> FloatArray:
        """Joints ``q``, the default free parameters and (symmetric) the spin closest to the hand
        at ``q``: the paper's minimal-rotation rule as the starting guess."""
        if not self.symmetric:
            return np.concatenate([q, self.default])
        pose = self.base_inv @ self.kin.grasp_pose(self.grasp, g=self.default)
        axis = self.axis(self.default)
        phi = float(minimal_spin(pose[:3, :3], axis, self.robot.fk(q)[:3, :3]))
        return np.concatenate([q, self.default, [phi]])

    def axis(self, g: FloatArray) -> FloatArray:
        """A symmetric grasp's unit axis in its own frame."""
        fn = self.kin.concept.function("grasp_axis", self.grasp)
        a = np.asarray(fn(self.kin.p, g), dtype=float).reshape(3)
        return a / np.linalg.norm(a)

    def grasp_frame(self, gs: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The grasp pose in the robot's base frame and its body Jacobian in the free
        parameters (6, m), then the spin (6, 1) for a symmetric grasp."""
        g = gs[: self.m]
        world, jac = self.kin.grasp_pose_jacobian(self.grasp, g=g)
        pose = self.base_inv @ world
        free = jac[:, self.joints :]  # columns: the object's joints first, then g
        rot = pose[:3, :3].T @ self.base_inv[:3, :3]  # world axes -> the grasp frame's axes
        body = np.vstack([rot @ free[:3], rot @ free[3:]])
        if not self.symmetric:
            return pose, body
        axis = self.axis(g)
        spin = pin.exp3(axis * float(gs[self.m]))
        pose = pose.copy()
        pose[:3, :3] = pose[:3, :3] @ spin  # G Rot(a, phi): the spin leaves the origin in place
        body = np.vstack([spin.T @ body[:3], spin.T @ body[3:]])
        return pose, np.hstack([body, np.concatenate([np.zeros(3), axis])[:, None]])

    def world_pose(self, gs: FloatArray) -> FloatArray:
        """The (spun) grasp pose in the world, from the pose function ``grasp:NAME``."""
        pose = self.kin.grasp_pose(self.grasp, g=gs[: self.m])
        if self.symmetric:
            pose = pose.copy()
            pose[:3, :3] = pose[:3, :3] @ pin.exp3(self.axis(gs[: self.m]) * float(gs[-1]))
        return pose

    def linearize(self, x: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        q, g = x[: self.n], x[self.n :]
        frame = self.robot.tcp_frame
        pin.computeJointJacobians(self.model, self.data, q)
        now = pin.updateFramePlacement(self.model, self.data, frame)
        j_robot = pin.getFrameJacobian(self.model, self.data, frame, pin.LOCAL)
        goal, j_grasp = self.grasp_frame(g)
        diff = now.actInv(pin.SE3(goal[:3, :3], goal[:3, 3]))
        err = pin.log6(diff).vector
        jac = np.hstack([-pin.Jlog6(diff.inverse()) @ j_robot, pin.Jlog6(diff) @ j_grasp])
        pos = float(np.linalg.norm(goal[:3, 3] - now.translation))
        score = max(pos / self.opts.tol_pos, float(np.linalg.norm(err[3:])) / self.opts.tol_rot)
        return err, jac, score

    def random(self, rng: np.random.Generator) -> FloatArray:
        """Random joints, free parameters and spin within their bounds."""
        return rng.uniform(self.lower, self.upper)


def solve_grasp_ik(
    robot: Robot,
    inst: Any,
    grasp: str,
    q0: Any = None,
    *,
    base: Any = None,
    scene: CollisionScene | None = None,
    seed: int = 0,
    options: IKOptions | None = None,
) -> GraspIKResult:
    """Joints and free grasp parameters that put the gripper on grasp family ``grasp`` of
    ``inst``, the robot's base at world pose ``base`` (default the world origin).

    Starts from ``q0`` (default ``robot.home``: a posture with room to move, which the action
    that follows needs) and the grasp's default free parameters, restarts from the seed bank's
    configurations whose gripper lies nearest the default grasp (``options.bank_seeds + 1``, the
    ones pose IK would try), then from seeded random joints and free parameters. With a
    collision ``scene`` (built for the same base and instance), a solution whose arm or palm
    touches anything is rejected and the search goes on; the fingers may touch the object.
    Failures are reasons, never exceptions: ``unreachable``, ``collision``, ``time_limit``.
    """
    opts = options or IKOptions()
    base_m = np.eye(4) if base is None else rigid_pose(base, "the robot base pose")
    problem = _GraspProblem(robot, Kinematics.of(inst), grasp, np.linalg.inv(base_m), opts)
    start = time.perf_counter()
    default = problem.base_inv @ problem.world_pose(problem.start(robot.home)[problem.n :])
    near = list(seed_bank(robot).nearest(default, opts.bank_seeds + 1))  # as many as pose IK
    x = problem.start(robot.home if q0 is None else robot.check_q(q0))
    rng = np.random.default_rng(seed)

    def restart() -> FloatArray:
        return problem.start(near.pop(0)) if near else problem.random(rng)

    clear = None if scene is None else (lambda x: not scene.collides(x[: robot.nq]))
    found = search(problem, x, opts, thread_qp(robot, len(x)), restart, clear)
    return _result(problem, found, start)


def _result(problem: _GraspProblem, found: Search, start: float) -> GraspIKResult:
    """Errors measured afresh: the robot's FK against the grasp pose from ``grasp:NAME`` (the
    pose function, not the Jacobian kernel the iteration used)."""
    q, g = found.x[: problem.n].copy(), found.x[problem.n :].copy()
    q.setflags(write=False)
    world_goal = problem.world_pose(g)
    world_goal.setflags(write=False)
    pose, err_pos, err_rot, within = measure(
        problem.robot, q, problem.base_inv @ world_goal, problem.opts
    )
    reason = found.reason
    success = reason == "converged" and within
    if reason == "converged" and not success:
        reason = "unreachable"
    names = problem.kin.free_parameters(problem.grasp)
    return GraspIKResult(
        success,
        q,
        pose,
        err_pos,
        err_rot,
        found.iterations,
        found.restarts,
        time.perf_counter() - start,
        reason,
        problem.grasp,
        {n: float(v) for n, v in zip(names, g)},
        world_goal,
        float(g[-1]) if problem.symmetric else 0.0,
    )
