"""Torque control of the simulated Panda: joint-space tracking and a compliant hand.

Two laws, both on top of the arm's gravity compensation (``grace_dsl.sim.arm``):

- ``JointTracker``: the planned joint trajectory (the approach and the move in), followed with
  the joint impedance gains of Franka's own joint-impedance example (600 N m/rad on the big
  joints down to 50 on the wrist) and the mass matrix times the reference acceleration as
  feed-forward, so that the arm stays on the collision-checked path.
- ``HandImpedance``: during the interaction the hand is a Cartesian spring-damper through the
  arm's Jacobian, ``tau = J^T (K e - D v)``, with the flying hand's stiffness and force caps
  (``grace_dsl.sim.control.Impedance``), its target the path follower's (re-anchored on the
  measured joint value). The arm's redundancy goes to a weak joint spring toward the plan's
  posture at that joint value, projected into the Jacobian's null space, so the elbow stays on
  the branch the planner checked while the hand alone decides the contact.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from grace_dsl.sim.arm import ArmWorld
from grace_dsl.sim.control import Impedance, quat_of

JOINT_KP = np.array([600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0])  # N m/rad
JOINT_KD = np.array([50.0, 50.0, 50.0, 20.0, 20.0, 20.0, 10.0])  # N m s/rad
HAND_DAMPING = 120.0  # N s/m: about critical for 1500 N/m on the arm's 2-3 kg at the hand
HAND_ROT_DAMPING = 3.0  # N m s/rad
NULL_KP = 15.0  # N m/rad toward the planned posture, in the null space only
NULL_KD = 3.0  # N m s/rad


def inertial(world: ArmWorld, acceleration: np.ndarray) -> np.ndarray:
    """The arm's joint torques ``M a`` for joint accelerations ``a`` (motor armature included;
    the object and the fingers at rest)."""
    vec = np.zeros(world.model.nv)
    vec[world.arm_dof] = acceleration
    out = np.zeros(world.model.nv)
    mujoco.mj_mulM(world.model, world.data, out, vec)
    return out[world.arm_dof]


@dataclass(frozen=True)
class JointTrajectory:
    """Joint waypoints ``q`` (K, 7) at times ``t`` (K,), sampled linearly in between."""

    q: np.ndarray
    t: np.ndarray

    def at(self, time: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, acceleration) of the reference at ``time`` (held at the ends)."""
        t = float(np.clip(time, self.t[0], self.t[-1]))
        k = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2))
        span = max(float(self.t[k + 1] - self.t[k]), 1e-9)
        s = (t - float(self.t[k])) / span
        q = (1 - s) * self.q[k] + s * self.q[k + 1]
        v = (self.q[k + 1] - self.q[k]) / span
        if time >= self.t[-1] or time <= self.t[0]:
            return q, np.zeros_like(q), np.zeros_like(q)
        # acceleration: the change of the segment velocities across the nearer waypoint
        j = k if s < 0.5 else k + 1
        if 0 < j < len(self.t) - 1:
            before = (self.q[j] - self.q[j - 1]) / max(float(self.t[j] - self.t[j - 1]), 1e-9)
            after = (self.q[j + 1] - self.q[j]) / max(float(self.t[j + 1] - self.t[j]), 1e-9)
            a = (after - before) / max(float(self.t[j + 1] - self.t[j - 1]) / 2, 1e-9)
        else:
            a = np.zeros_like(q)
        return q, v, a


def track_torque(
    world: ArmWorld, q_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray
) -> np.ndarray:
    """Joint impedance toward ``(q_ref, v_ref)`` plus the inertial feed-forward ``M a_ref``."""
    e = q_ref - world.arm_q()
    de = v_ref - world.arm_dq()
    return JOINT_KP * e + JOINT_KD * de + inertial(world, a_ref)


@dataclass
class HandImpedance:
    """The hand pulled toward a target pose through the arm's Jacobian; a posture spring in
    the null space."""

    spring: Impedance = field(default_factory=Impedance)
    damping: float = HAND_DAMPING
    rot_damping: float = HAND_ROT_DAMPING
    _target: np.ndarray | None = None
    _quat: np.ndarray | None = None

    def torque(self, world: ArmWorld, target: np.ndarray, posture: np.ndarray) -> np.ndarray:
        if target is not self._target or self._quat is None:
            self._target, self._quat = target, quat_of(target)
        d, b = world.data, world.hand_body
        jac = world.jacobian()
        dq = world.arm_dq()
        twist = jac @ dq
        wrench = self.spring.wrench_at(
            d.xpos[b].copy(), d.xmat[b].reshape(3, 3), target[:3, 3], self._quat
        )
        wrench[:3] -= self.damping * twist[:3]
        wrench[3:] -= self.rot_damping * twist[3:]
        tau = jac.T @ wrench
        pinv = np.linalg.pinv(jac, rcond=1e-3)
        null = np.eye(len(dq)) - jac.T @ pinv.T
        tau_posture = NULL_KP * (posture - world.arm_q()) - NULL_KD * dq
        return tau + null @ tau_posture
