"""A room of several objects and the full Panda on a movable base: sub-tasks one after another.

``MultiWorld`` (``grace_dsl.sim.multi``) gives the flying hand a persistent world of several
objects; this is the same world for the arm of ``grace_dsl.sim.arm``. Every object of the scene
is compiled into one MuJoCo model (floor, lights, camera, names prefixed ``obj<i>/``, made
physical as ``MultiWorld`` makes them) with the arm attached under ``arm/``. The model persists:
what one action leaves (a drawer open) is there for the next.

The arm's base (``panda_link0``) is a mocap body. ``act`` TELEPORTS it to the base pose the
planner chose for the sub-task (``ActionPlan.base``) with the arm folded in its plan's start
posture, as a mobile manipulator would drive there with its arm stowed; the drive itself is not
simulated. From there the plan runs as a single-object arm episode runs it
(``arm_episode.execute_plan``: joint-space approach, pinch, compliant interaction through the
arm's Jacobian, release, retreat), on this world's state. The base stands at whatever height the
plan gives it (a pedestal on a lift column, drawn but not colliding: the grasps
``placement.HEIGHT`` above it, which can be below the floor for a low handle), so the floor is
no obstacle for the arm (nor is it for the planner); the objects are, for both.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.arm import ARM_JOINTS, ARM_LINKS, ArmWorld, arm_body, panda_chain
from grace_dsl.sim.camera import Camera
from grace_dsl.sim.episode import Outcome
from grace_dsl.sim.hand import OBJECT_GROUP, HandSpec, quat_wxyz
from grace_dsl.sim.multi import Room
from grace_dsl.sim.protocol import TaskAction

if TYPE_CHECKING:
    from grace_dsl.robot.act import ActionPlan

ARM = "arm/"  # the prefix of the arm's names in the world
PARK = np.array([0.0, 0.0, -5.0])  # m: where the base waits before its first sub-task
COLUMN = 3.0  # m: the drawn lift column under the base (hidden below the floor)


@dataclass(frozen=True)
class ArmAct:
    """What one ``act`` did: the joint before and after, the arm's start and end postures, the
    base pose it stood at, and the execution's own account."""

    object: str
    joint: str
    q_before: float
    q_after: float
    outcome: Outcome
    sim_seconds: float
    base: np.ndarray  # 4x4 world pose of panda_link0
    arm_before: tuple[float, ...]
    arm_after: tuple[float, ...]


class ArmMultiWorld(Room):
    """Several posed instances (world poses, as ``multi.place`` gives) and the Panda arm."""

    def __init__(
        self,
        objects: Sequence[tuple[str, Instance]],
        gripper: Gripper | None = None,
        camera: Camera | None = None,
    ):
        self._set_objects(objects, camera)
        self.gripper = gripper or Gripper.panda()
        arm_xml, hand = _arm_spec(self.gripper)
        model, data = self.scene.compile(extra=[(mujoco.MjSpec.from_string(arm_xml), ARM)])
        hand = replace(
            hand,
            body=ARM + hand.body,
            fingers=tuple(ARM + f for f in hand.fingers),
            actuators=tuple(ARM + a for a in hand.actuators),
        )
        floor = model.geom("floor").id
        model.geom_conaffinity[floor] = OBJECT_GROUP  # the floor holds the objects, not the arm
        self._index_joints(model)
        arm_bodies = {model.body(ARM + n).id for n in ARM_LINKS}
        ours = {b for b in range(model.nbody) if model.body(b).name.startswith(ARM)}
        self._mocap = int(model.body_mocapid[model.body(ARM + "panda_link0").id])
        self.arm = ArmWorld(
            model,
            data,
            hand,
            np.eye(4),
            {},
            np.array([model.joint(ARM + n).qposadr[0] for n in ARM_JOINTS]),
            np.array([model.joint(ARM + n).dofadr[0] for n in ARM_JOINTS]),
            np.array([model.actuator(f"{ARM}{n}_motor").id for n in ARM_JOINTS]),
            panda_chain().effort,
            model.body(hand.body).id,
            frozenset(g for g in range(model.ngeom) if model.geom_bodyid[g] in arm_bodies),
            frozenset(
                g
                for g in range(model.ngeom)
                if model.geom_bodyid[g] not in ours and model.geom_bodyid[g] != 0
            ),
        )
        self.arm.set_fingers(self.gripper.max_width, at_once=True)
        for finger in hand.fingers:
            data.qpos[model.joint(finger).qposadr[0]] = self.arm.finger_goal
        base = np.eye(4)
        base[:3, 3] = PARK
        self.place_base(base, np.zeros(len(ARM_JOINTS)))

    # -- reading
    @property
    def time(self) -> float:
        return self.arm.time

    def _state(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        return self.arm.model, self.arm.data

    def arm_q(self) -> np.ndarray:
        """The arm's seven measured joint angles."""
        return self.arm.arm_q()

    def base(self) -> np.ndarray:
        """The base's current world pose."""
        pose = np.eye(4)
        pose[:3, 3] = self.arm.data.mocap_pos[self._mocap]
        mujoco.mju_quat2Mat(pose[:3, :3].reshape(9), self.arm.data.mocap_quat[self._mocap])
        return pose

    # -- acting
    def place_base(self, base: np.ndarray, q: np.ndarray) -> None:
        """Teleport the base to world pose ``base`` with the arm at rest in posture ``q``."""
        d = self.arm.data
        d.mocap_pos[self._mocap] = base[:3, 3]
        d.mocap_quat[self._mocap] = quat_wxyz(base)
        d.qpos[self.arm.arm_qpos] = np.asarray(q, float)
        d.qvel[self.arm.arm_dof] = 0.0
        self.arm.base = np.asarray(base, float).copy()
        mujoco.mj_forward(self.arm.model, d)

    def act(
        self,
        obj: str,
        task: TaskAction,
        plan: ActionPlan,
        goal: float | None = None,
        seconds: float = 20.0,
        inst: Instance | None = None,
    ) -> ArmAct:
        """Carry out ``plan`` (the robot layer's, for ``task`` on ``obj``): the base teleported
        to ``plan.base`` with the arm at the plan's first posture, then the plan executed until
        the joint reaches ``goal`` (default the episode's), at most ``seconds`` simulated
        seconds of interaction. ``inst``: the agent's model of the object (default the true
        one at its measured joints). The world keeps the result."""
        from grace_dsl.sim.arm_episode import execute_plan

        inst = self.instance(obj) if inst is None else inst
        q0 = self.q(obj, task.joint)
        arm_before = tuple(float(v) for v in self.arm_q())
        self.place_base(plan.base, plan.q[0])
        view = replace(self.arm, joint_qpos=self._addresses(obj))
        began = self.time
        out = execute_plan(inst, task, plan, seconds, world=view, goal=goal)
        self.arm.finger_goal = view.finger_goal
        return ArmAct(
            obj,
            task.joint,
            q0,
            self.q(obj, task.joint),
            out,
            self.time - began,
            np.asarray(plan.base, float).copy(),
            arm_before,
            tuple(float(v) for v in self.arm_q()),
        )


def base_yaw(base: np.ndarray) -> float:
    """The base's heading about world z (radians)."""
    return math.atan2(float(base[1, 0]), float(base[0, 0]))


def _arm_spec(gripper: Gripper) -> tuple[str, HandSpec]:
    """The arm (its base a mocap body, so a sub-task can put it anywhere) as a stand-alone MJCF
    document, attached to the scene's world."""
    spec, assets, body, actuators = arm_body(np.eye(4), gripper)
    body.set("mocap", "true")
    ET.SubElement(  # the lift column the pedestal stands on: seen by the camera, touches nothing
        body,
        "geom",
        name="column",
        type="cylinder",
        size=f"0.07 {COLUMN / 2:g}",
        pos=f"0 0 {-COLUMN / 2:g}",
        contype="0",
        conaffinity="0",
        rgba="0.3 0.3 0.32 1",
    )
    root = ET.Element("mujoco", model="arm")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "asset").extend(assets)
    ET.SubElement(root, "worldbody").append(body)
    ET.SubElement(root, "actuator").extend(actuators)
    for mesh in root.iter("mesh"):
        mesh.set("file", str(Path(mesh.get("file", "")).resolve()))
    return ET.tostring(root, encoding="unicode"), spec
