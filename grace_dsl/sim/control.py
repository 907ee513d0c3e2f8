"""Compliant following of an analytic path: the object's joint, not the clock, sets the pace.

The runtime gives the hand's path as a function of the joint value (``inst.follow``: the hand
rides the moving link). A controller that replays it against time fights the object whenever the
real joint lags (friction, a stiff hinge, a slipping contact) and tears the hand off the part.
Here the target is re-anchored on the MEASURED joint value each step: the hand is pulled towards
the path's pose a short lead ahead of where the joint is now (``PathFollower``), through a
Cartesian spring (``Impedance``) whose force is capped. If the joint stops, the target stops a
lead ahead, so the hand presses with a bounded force instead of running away; if the joint moves
the other way, the target follows it back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from grace_dsl.runtime.instance import Instance

LEAD = 0.04  # m the target runs ahead of the hand's pose at the measured joint value
ROT_RADIUS = 0.05  # m: a radian of hand rotation counts as this much travel (a knob's twist)
SPEED = 0.15  # m/s of hand travel along the path: slow enough that a part does not coast
MIN_RATE = 1e-4  # m per joint unit below which the joint does not move the hand


@dataclass(frozen=True)
class PathFollower:
    """The hand's target as a function of the measured joint value.

    ``attached`` is the hand pose in the moving link's frame, fixed at the grasp: the path at q
    is ``pose @ link(q) @ attached``, exactly ``inst.follow``'s, evaluated at any q."""

    inst: Instance
    joint: str
    attached: np.ndarray
    goal: float  # joint value the target never passes
    sign: float  # +1 opening (q grows), -1 closing
    lead: float = LEAD
    speed: float = SPEED  # m/s the reference may move the hand along the path

    @staticmethod
    def from_grasp(
        inst: Instance, joint: str, hand_pose: np.ndarray, goal: float, sign: float
    ) -> PathFollower:
        """Attach ``hand_pose`` (world) to the joint's child link at the instance's joint values."""
        at = link_world(inst, joint, inst.q)
        return PathFollower(inst, joint, np.linalg.solve(at, hand_pose), goal, sign)

    def pose_at(self, q: float) -> np.ndarray:
        """The hand's pose on the path at joint value ``q`` (the other joints as instantiated)."""
        qs = np.array(self.inst.q, dtype=float)
        qs[self.inst.concept.joint_index[self.joint]] = q
        return link_world(self.inst, self.joint, qs) @ self.attached

    def lookahead(self, q: float) -> float:
        """Joint units that move the hand about ``lead`` along the path from ``q``."""
        dq = 1e-3 * self.sign
        a, b = self.pose_at(q), self.pose_at(q + dq)
        travel = float(np.linalg.norm(b[:3, 3] - a[:3, 3]))
        rate = (travel + ROT_RADIUS * rotation_angle(a, b)) / 1e-3
        return self.lead / max(rate, MIN_RATE)

    def target(self, q_measured: float) -> np.ndarray:
        """The pose a lead ahead of the measured joint value, never beyond the goal."""
        return self.pose_at(self.ahead(q_measured))

    def ahead(self, q_measured: float) -> float:
        """The joint value a lead ahead of the measured one, never beyond the goal."""
        ahead = q_measured + self.sign * self.lookahead(q_measured)
        return min(ahead, self.goal) if self.sign > 0 else max(ahead, self.goal)

    def advance(self, q_measured: float, q_ref: float, dt: float) -> float:
        """The next reference joint value: towards ``ahead(q_measured)``, but no faster than
        ``speed`` (m/s of hand travel) from ``q_ref``; it falls back at once if the joint lags,
        so the hand never runs more than a lead ahead of the part."""
        want = self.ahead(q_measured)
        step = self.lookahead(q_ref) * self.speed * dt / self.lead
        if self.sign * (want - q_ref) <= 0:
            return want
        return q_ref + self.sign * min(self.sign * (want - q_ref), step)


def link_world(inst: Instance, joint: str, q: np.ndarray) -> np.ndarray:
    """World pose of ``joint``'s child link at joint vector ``q``."""
    child = inst.concept.joints[joint].child
    link = inst.concept.function("link", child)
    return np.asarray(inst.pose, float) @ np.asarray(link(inst.p, q), float).reshape(4, 4)


def rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle (radians) of the rotation from pose ``a`` to pose ``b``."""
    rel = a[:3, :3].T @ b[:3, :3]
    return math.acos(max(-1.0, min(1.0, (np.trace(rel) - 1.0) / 2.0)))


def rotation_vector(r: np.ndarray) -> np.ndarray:
    """The axis-angle vector of rotation matrix ``r`` (robust near 0 and pi)."""
    angle = math.acos(max(-1.0, min(1.0, (np.trace(r) - 1.0) / 2.0)))
    if angle < 1e-9:
        return np.zeros(3)
    if angle > math.pi - 1e-4:  # near a half turn: the axis from the symmetric part
        m = (r + np.eye(3)) / 2.0
        axis = m[:, int(np.argmax(np.diag(m)))]
        return angle * axis / np.linalg.norm(axis)
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return angle * w / (2.0 * math.sin(angle))


@dataclass(frozen=True)
class Impedance:
    """A Cartesian spring on the hand's pose; damping lives on the hand's free joint (implicit).

    The force is capped so that a blocked hand presses, never crushes: ``max_force`` is what a
    person's push on a door handle might be, ``max_torque`` what a wrist turns a knob with."""

    stiffness: float = 1500.0  # N/m
    rot_stiffness: float = 40.0  # N m/rad
    max_force: float = 120.0  # N
    max_torque: float = 8.0  # N m

    def wrench(self, pose: np.ndarray, target: np.ndarray) -> np.ndarray:
        """The world (force, torque) 6-vector pulling ``pose`` towards ``target``."""
        return self.wrench_at(pose[:3, 3], pose[:3, :3], target[:3, 3], quat_of(target))

    def wrench_at(
        self, pos: np.ndarray, rot: np.ndarray, target_pos: np.ndarray, target_quat: np.ndarray
    ) -> np.ndarray:
        """``wrench`` from the hand's position and rotation matrix and the target's position
        and (w, x, y, z) quaternion: the per-step form, with MuJoCo's quaternion arithmetic."""
        force = self.stiffness * (target_pos - pos)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rot).reshape(-1))
        local = np.empty(3)
        mujoco.mju_subQuat(local, target_quat, quat)  # in the hand's frame
        torque = self.rot_stiffness * (rot @ local)
        return np.concatenate([_cap(force, self.max_force), _cap(torque, self.max_torque)])


def quat_of(pose: np.ndarray) -> np.ndarray:
    """The (w, x, y, z) quaternion of a pose's rotation (MuJoCo's convention)."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(pose[:3, :3], dtype=float).reshape(-1))
    return quat


def _cap(v: np.ndarray, limit: float) -> np.ndarray:
    n = math.sqrt(float(v @ v))
    return v if n <= limit else v * (limit / n)


def blend(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """The pose a fraction ``t`` from ``a`` to ``b``: positions linearly, rotations along the
    shortest arc (so an approach comes in straight and turns evenly)."""
    t = min(max(t, 0.0), 1.0)
    out = np.eye(4)
    out[:3, 3] = (1 - t) * a[:3, 3] + t * b[:3, 3]
    rel = rotation_vector(b[:3, :3] @ a[:3, :3].T) * t
    out[:3, :3] = _exp(rel) @ a[:3, :3]
    return out


def _exp(w: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(w))
    if angle < 1e-12:
        return np.eye(3)
    k = w / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx
