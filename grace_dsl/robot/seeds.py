"""A bank of joint configurations and their gripper poses, for starting IK near its target.

An IK attempt from a configuration whose gripper is far from the target (the home pose, a random
draw) takes more steps and more often stalls in a joint-limit corner than one that starts from a
configuration whose gripper is already close. The bank holds ``BANK_SIZE`` configurations drawn
uniformly within the joint limits (a fixed seed, independent of any target, so every solve is
reproducible) and the robot's home, with their forward kinematics, computed once per robot on
first use; :meth:`SeedBank.nearest` ranks them by gripper-pose distance to a target.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.spatial import cKDTree

from grace_dsl.robot.model import Robot

FloatArray = np.ndarray

BANK_SIZE = 16384
BANK_SEED = 20240917
ROTATION_WEIGHT = 0.1  # metres per unit of chordal rotation distance ‖R − R*‖_F
_BANKS: weakref.WeakKeyDictionary[Robot, SeedBank] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


@dataclass(frozen=True)
class SeedBank:
    """Configurations ``q`` (N, nq) and a k-d tree of their gripper poses as features in R¹²:
    the position, then ``ROTATION_WEIGHT`` times the rotation's nine entries."""

    q: FloatArray
    tree: cKDTree

    def nearest(self, goal: FloatArray, k: int) -> FloatArray:
        """The ``k`` configurations whose gripper poses lie closest to the 4x4 ``goal``, closest
        first, by ``‖p − p*‖² + w² ‖R − R*‖²_F`` (w = ``ROTATION_WEIGHT``)."""
        k = min(k, len(self.q))
        _, index = self.tree.query(_features(goal[:3, 3], goal[:3, :3]), k=k)
        return self.q[np.atleast_1d(index)]


def seed_bank(robot: Robot) -> SeedBank:
    """The robot's bank, built on first use (16,384 forward kinematics: about 0.1 s)."""
    bank = _BANKS.get(robot)
    if bank is None:
        with _LOCK:
            bank = _BANKS.get(robot)
            if bank is None:
                bank = _BANKS[robot] = build_bank(robot, BANK_SIZE, BANK_SEED)
    return bank


def build_bank(robot: Robot, size: int, seed: int) -> SeedBank:
    """``robot.home`` and ``size`` configurations drawn uniformly within the limits."""
    rng = np.random.default_rng(seed)
    qs = np.vstack([robot.home, rng.uniform(robot.lower, robot.upper, (size, robot.nq))])
    model, data, frame = robot.model, robot.model.createData(), robot.tcp_frame
    features = np.empty((len(qs), 12))
    for i, q in enumerate(qs):
        pin.forwardKinematics(model, data, q)
        pose = pin.updateFramePlacement(model, data, frame)
        features[i] = _features(pose.translation, pose.rotation)
    qs.setflags(write=False)
    return SeedBank(qs, cKDTree(features))


def _features(position: FloatArray, rotation: FloatArray) -> FloatArray:
    return np.concatenate([position, ROTATION_WEIGHT * np.asarray(rotation).reshape(9)])
