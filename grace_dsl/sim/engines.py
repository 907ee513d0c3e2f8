"""The physics engines a flying-hand episode runs on, and the small interface it drives.

An episode (``grace_dsl.sim.episode``) reads and drives its world through ``HandWorld`` alone:
place the hand, step towards a target pose, read a joint, the hand's pose and its opening, move
the fingers. MuJoCo's ``World`` (``grace_dsl.sim.world``, the default) and SAPIEN's
``SapienWorld`` (``grace_dsl.sim.sapien_world``, PhysX on CPU) both offer it, so the same
draws, option, controller and success criteria run on either engine.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.hand import HandSpec

ENGINES = ("mujoco", "sapien")


class HandWorld(Protocol):
    """What an episode needs of a world with one object and one flying hand."""

    hand: HandSpec
    trace_every: int

    @property
    def time(self) -> float: ...

    @property
    def timestep(self) -> float: ...

    def q(self, joint: str) -> float: ...

    def qdot(self, joint: str) -> float: ...

    def hand_pose(self) -> np.ndarray: ...

    def opening(self) -> float: ...

    def unstable(self) -> bool: ...

    def place_hand(self, pose: np.ndarray) -> None: ...

    def set_fingers(self, width: float, at_once: bool = False) -> None: ...

    def step(self, target: np.ndarray) -> None: ...


def build_world(
    engine: str,
    inst: Instance,
    gripper: Gripper,
    hand_pose: np.ndarray,
    driven: str | None = None,
) -> HandWorld:
    """A new world of ``inst`` with the hand at ``hand_pose`` on ``engine`` (balanced, only the
    ``driven`` joint's part weightless: ``World.build``)."""
    if engine == "mujoco":
        from grace_dsl.sim.world import World

        return World.build(inst, gripper, hand_pose, driven=driven)
    if engine == "sapien":
        from grace_dsl.sim.sapien_world import SapienWorld

        return SapienWorld.build(inst, gripper, hand_pose, driven=driven)
    raise ParameterError(f"engine {engine!r} is unknown: use one of {ENGINES}")
