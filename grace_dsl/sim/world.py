"""One concept instance and one flying hand in a MuJoCo world, stepped under impedance control.

The object comes from the MJCF export (its root welded to the world at the instance pose); the
hand from ``grace_dsl.sim.hand``. The object's own bodies do not collide with each other: its
joints' ranges already keep the parts where they belong, and the export's collision shapes may
still overlap at rest (a carcass exported as a solid block around its drawer). The hand collides
with every part of the object.

The parts are balanced against gravity by default (gravity compensation on the object's bodies):
a bottom-hinged oven door would otherwise fall open and a lid fall shut before the hand arrives,
where the real ones are held by a counterbalance spring or a friction hinge. The protocol places
the joint where it starts, and the part stays there until the hand moves it. The export holds a
closed part shut by a friction loss sized to gravity's pull; balanced, that friction would only
resist the hand (an oven door then opened past half its range in 65% of episodes, not 100%), so
the world gives the joint the hand drives the export's base friction instead. Told which joint
the hand drives, the world balances only the part that joint moves (and what hangs on it): the
other parts keep their weight and the export's holding friction, so a toilet seat stays down on
its stop while the hand lifts the lid hinged on it (weightless, it rose with the lid).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import mujoco
import numpy as np

from grace_dsl.export.mjcf import write_mjcf
from grace_dsl.export.model import FRICTION, build_model
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.control import Impedance, quat_of
from grace_dsl.sim.hand import GRASP_FORCE, HAND_GROUP, OBJECT_GROUP, HandSpec, build_hand

TIMESTEP = 0.002  # s
FINGER_SPEED = 0.1  # m/s per finger: panda.urdf's finger joint velocity limit is 0.2
LINEAR_DAMPING = 70.0  # N s/m on the hand's free joint: about critical for 1500 N/m, 0.76 kg
ANGULAR_DAMPING = 0.8  # N m s/rad
ANGULAR_ARMATURE = 0.003  # kg m^2 added to the hand's rotation (a stiffer spring stays stable)
#: the object's bodies collide with each other too (the export's own exclusions kept): off by
#: default; docs/benchmarks.md has the measured difference
SELF_COLLISION = False


@dataclass
class World:
    """A compiled MuJoCo model and its state, with the names an episode reads and drives."""

    model: mujoco.MjModel
    data: mujoco.MjData
    hand: HandSpec
    joint_qpos: dict[str, int]  # concept joint name -> qpos address
    hand_body: int
    impedance: Impedance
    finger_goal: float = 0.0
    #: every ``trace_every`` steps (0: never), the time, the joint positions and every body's
    #: position and (w, x, y, z) quaternion: what a replay of the episode draws
    trace_every: int = 0
    trace: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    _steps: int = 0
    _target: np.ndarray | None = None
    _target_quat: np.ndarray | None = None

    @staticmethod
    def build(
        inst: Instance,
        gripper: Gripper,
        hand_pose: np.ndarray,
        impedance: Impedance | None = None,
        balanced: bool = True,
        driven: str | None = None,
        self_collision: bool | None = None,
    ) -> World:
        """The world of ``inst`` (joints at its values) with the hand at ``hand_pose``;
        ``balanced``: the object's parts do not fall under gravity (see the module docstring);
        ``driven``: the concept joint the hand moves (None: every joint); in a balanced world
        only its part is balanced and loses the export's holding friction; ``self_collision``
        (default ``SELF_COLLISION``): the object's own bodies collide with each other."""
        exported = build_model(inst)
        root = ET.fromstring(write_mjcf(exported))
        for key in root.findall("keyframe"):  # its qpos no longer fits once the hand is in
            root.remove(key)
        if balanced:  # a real door or lid is counterbalanced or held by a friction hinge
            free = {j.name for j in exported.joints if driven in (None, j.source)}
            for body in _moved_by(root, free):
                body.set("gravcomp", "1")
            for joint in root.iter("joint"):  # no gravity to hold against: a hinge's own friction
                if joint.get("name") in free:
                    joint.set("frictionloss", str(FRICTION))
        for geom in root.iter("geom"):
            if geom.get("contype") == "0" and geom.get("conaffinity") == "0":
                continue  # a visual geom (the export's whole pieces): it collides with nothing
            geom.set("contype", str(OBJECT_GROUP))
            among = SELF_COLLISION if self_collision is None else self_collision
            geom.set("conaffinity", str(HAND_GROUP | (OBJECT_GROUP if among else 0)))
        spec, assets, body, actuators = build_hand(gripper, hand_pose, GRASP_FORCE)
        option = ET.Element("option", timestep=str(TIMESTEP), integrator="implicitfast")
        option.set("gravity", "0 0 -9.81")
        root.insert(0, option)
        asset = root.find("asset")
        if asset is None:
            asset = ET.Element("asset")
            root.insert(2, asset)
        asset.extend(assets)
        world = root.find("worldbody")
        assert world is not None
        ET.SubElement(world, "light", pos="0 0 4", dir="0 0 -1", directional="true")
        world.append(body)
        if actuators:
            ET.SubElement(root, "actuator").extend(actuators)
        model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
        data = mujoco.MjData(model)
        free = model.joint("hand_free")
        dof = free.dofadr[0]
        model.dof_damping[dof : dof + 3] = LINEAR_DAMPING
        model.dof_damping[dof + 3 : dof + 6] = ANGULAR_DAMPING
        model.dof_armature[dof + 3 : dof + 6] += ANGULAR_ARMATURE
        addresses = {}
        for j in exported.joints:
            if j.kind != "fixed" and j.source in inst.concept.joint_index:
                adr = int(model.joint(j.name).qposadr[0])
                addresses[j.source] = adr
                data.qpos[adr] = inst.joints[j.source]
        w = World(model, data, spec, addresses, model.body("hand").id, impedance or Impedance())
        w.set_fingers(0.0, at_once=True)
        mujoco.mj_forward(model, data)
        return w

    # -- reading
    @property
    def time(self) -> float:
        return float(self.data.time)

    def q(self, joint: str) -> float:
        """The measured value of a concept joint."""
        return float(self.data.qpos[self.joint_qpos[joint]])

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def qdot(self, joint: str) -> float:
        """The measured velocity of a concept joint."""
        adr = self.joint_qpos[joint]
        jnt = int(np.flatnonzero(self.model.jnt_qposadr == adr)[0])
        return float(self.data.qvel[int(self.model.jnt_dofadr[jnt])])

    def hand_pose(self) -> np.ndarray:
        """The hand's measured world pose (the gripper frame)."""
        pose = np.eye(4)
        pose[:3, :3] = self.data.xmat[self.hand_body].reshape(3, 3)
        pose[:3, 3] = self.data.xpos[self.hand_body]
        return pose

    def opening(self) -> float:
        """The measured distance between the pads' inner faces."""
        return float(sum(self.data.qpos[self.model.joint(j).qposadr[0]] for j in self.hand.fingers))

    def unstable(self) -> bool:
        """The state blew up (MuJoCo flags a bad acceleration and resets it)."""
        return bool(self.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number) or not all(
            map(math.isfinite, self.data.qpos)
        )

    # -- driving
    def place_hand(self, pose: np.ndarray) -> None:
        """Put the hand at ``pose`` at rest with its fingers shut, as ``build`` does: a flying
        hand moved to the next pre-grasp of a world that persists between actions."""
        free = int(self.model.body_jntadr[self.hand_body])  # the hand body's free joint
        adr, dof = int(self.model.jnt_qposadr[free]), int(self.model.jnt_dofadr[free])
        self.data.qpos[adr : adr + 3] = pose[:3, 3]
        self.data.qpos[adr + 3 : adr + 7] = quat_of(pose)
        self.data.qvel[dof : dof + 6] = 0.0
        for name in self.hand.fingers:
            j = self.model.joint(name)
            self.data.qpos[j.qposadr[0]] = 0.0
            self.data.qvel[j.dofadr[0]] = 0.0
        self._target = self._target_quat = None
        self.set_fingers(0.0, at_once=True)
        mujoco.mj_forward(self.model, self.data)

    def set_fingers(self, width: float, at_once: bool = False) -> None:
        """Command the pads ``width`` apart (each finger half of it; force capped). The command
        moves at the real finger speed (``FINGER_SPEED``) unless ``at_once``."""
        self.finger_goal = min(max(width / 2, 0.0), self.hand.finger_travel)
        if at_once:
            for name in self.hand.actuators:
                self.data.ctrl[self.model.actuator(name).id] = self.finger_goal

    def _ramp_fingers(self) -> None:
        step = FINGER_SPEED * self.model.opt.timestep
        for name in self.hand.actuators:
            i = self.model.actuator(name).id
            now = float(self.data.ctrl[i])
            self.data.ctrl[i] = now + max(-step, min(step, self.finger_goal - now))

    def step(self, target: np.ndarray) -> None:
        """One physics step with the impedance wrench towards ``target`` at the gripper origin."""
        if target is not self._target or self._target_quat is None:  # once per new target
            self._target, self._target_quat = target, quat_of(target)
        d, b = self.data, self.hand_body
        self._ramp_fingers()
        d.qfrc_applied[:] = 0.0
        pos = d.xpos[b].copy()
        w = self.impedance.wrench_at(pos, d.xmat[b].reshape(3, 3), target[:3, 3], self._target_quat)
        mujoco.mj_applyFT(self.model, d, w[:3], w[3:], pos, b, d.qfrc_applied)
        mujoco.mj_step(self.model, d)
        if self.trace_every and self._steps % self.trace_every == 0:
            self.trace.append((float(d.time), d.qpos.copy(), d.xpos.copy(), d.xquat.copy()))
        self._steps += 1


def _moved_by(root: ET.Element, joints: set[str]) -> list[ET.Element]:
    """Every body of the MJCF ``root`` that one of ``joints`` moves (its child and below)."""
    out: list[ET.Element] = []
    for body in root.iter("body"):
        if any(j.get("name") in joints for j in body.findall("joint")):
            out.extend(body.iter("body"))
    return list({id(b): b for b in out}.values())
