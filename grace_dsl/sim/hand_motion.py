"""How a flying hand may move: a hand whose wrist cannot turn only translates.

A top-down, translate-only gripper (``Gripper.can_turn`` false: a mocap hand or a gantry) keeps
the orientation it approached with for the whole episode. ``inst.follow`` carries the hand
rigidly with the moving link, so on a hinge its path turns the hand; such a hand follows the
path's positions only, its target rotation fixed at the grasp's. ``rank`` offers such a hand no
pinch whose path turns it, so what it follows this way is a push or a hook (the contact slides)
or a pinch on a link that translates.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.control import PathFollower


@dataclass(frozen=True)
class TranslatingFollower(PathFollower):
    """A ``PathFollower`` whose targets keep one world rotation (a hand that cannot turn)."""

    rotation: np.ndarray = field(default_factory=lambda: np.eye(3), compare=False)

    def pose_at(self, q: float) -> np.ndarray:
        pose = super().pose_at(q).copy()
        pose[:3, :3] = self.rotation
        return pose


def follower_for(
    gripper: Gripper,
    inst: Instance,
    joint: str,
    hand_pose: np.ndarray,
    goal: float,
    sign: float,
) -> PathFollower:
    """The path follower this hand can execute: the path itself for a hand that turns; for one
    that cannot, the path's positions with the rotation held at ``hand_pose``'s."""
    base = PathFollower.from_grasp(inst, joint, hand_pose, goal, sign)
    if gripper.can_turn:
        return base
    return TranslatingFollower(
        base.inst,
        base.joint,
        base.attached,
        base.goal,
        base.sign,
        base.lead,
        base.speed,
        rotation=np.array(hand_pose[:3, :3], dtype=float),
    )
