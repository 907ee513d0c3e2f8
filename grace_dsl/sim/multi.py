"""A persistent world of several objects and one flying hand: sub-tasks one after another.

A benchmark episode (``grace_dsl.sim.episode``) builds a fresh world for one object and one
action. A long task acts on several objects in turn, and what one step did must still be there
for the next (the drawer opened first is still open when the door is closed). ``MultiWorld``
compiles every object into one MuJoCo model (``grace_dsl.sim.scene``: names prefixed
``obj<i>/``, floor, lights and camera), adds the hand, and keeps that model's state for its
whole life. ``act`` carries out one action on one object to a joint value with the same
approach, grasp, compliant following and release as an episode (``episode.execute`` on a view
of this world that reads that object's joints), then the hand backs off; the next ``act`` puts
the flying hand at its next pre-grasp, as the paper's protocol places a flying gripper.

The objects are made physical as ``World.build`` makes one: their parts balanced against
gravity, their joints given the export's base friction, their collision pieces touching the hand
(and the floor) but not each other.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from grace_dsl.export.model import FRICTION
from grace_dsl.runtime.errors import GraceError, ParameterError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.manipulation import Option
from grace_dsl.sim.camera import Camera
from grace_dsl.sim.control import Impedance
from grace_dsl.sim.episode import Outcome, execute
from grace_dsl.sim.hand import GRASP_FORCE, HAND_GROUP, OBJECT_GROUP, HandSpec, build_hand
from grace_dsl.sim.model import zup_pose
from grace_dsl.sim.protocol import TaskAction
from grace_dsl.sim.scene import CLEARANCE, Frame, Scene
from grace_dsl.sim.world import ANGULAR_ARMATURE, ANGULAR_DAMPING, LINEAR_DAMPING, World

HAND = "hand/"  # the prefix of the hand's names in the world
PARK = np.array([0.0, 0.0, 3.0])  # m: where the hand waits, far above every object


class MultiWorldError(GraceError, ValueError):
    """A multi-object world asked for something it does not hold: an unknown object or joint,
    two objects with one name."""


def place(inst: Instance, position: Sequence[float], yaw: float = 0.0) -> Instance:
    """``inst`` standing in a z-up world: its concept origin above ``position``'s x, y, its
    lowest point (joints closed) ``position[2]`` above the floor, its front (concept +z) facing
    world +x turned by ``yaw`` radians about world z."""
    x, y, z = (float(v) for v in position)
    pose = zup_pose(inst, (x, y), yaw + math.pi / 2)
    pose[2, 3] += z + CLEARANCE
    return inst.with_pose(pose)


@dataclass(frozen=True)
class Act:
    """What one ``act`` did: the joint before and after, and the execution's own account."""

    object: str
    joint: str
    q_before: float
    q_after: float
    outcome: Outcome
    sim_seconds: float  # simulated time this action took


class Room(ABC):
    """What a world of several posed objects knows of them, whoever acts in it (the flying
    hand's ``MultiWorld``, the arm's ``ArmMultiWorld``): their names, the instances as placed,
    the scene, and where each object's movable joints sit in the compiled model's state. The
    measured joints are read back through it."""

    names: tuple[str, ...]
    scene: Scene
    _initial: dict[str, Instance]
    _joints: dict[str, dict[str, int]]

    def _set_objects(self, objects: Sequence[tuple[str, Instance]], camera: Camera | None) -> None:
        """Check the objects' names and build their scene (``objects`` as ``place`` gives)."""
        names = [n for n, _ in objects]
        if not objects:
            raise MultiWorldError("a world needs at least one object")
        if len(set(names)) != len(names):
            raise MultiWorldError(f"object names must be unique, got {names}")
        self.names = tuple(names)
        self._initial = {n: inst for n, inst in objects}
        scene = Scene.from_instances([i for _, i in objects], camera=camera, up="keep")
        self.scene = replace(scene, texts=tuple(_physical(t) for t in scene.texts))

    def _index_joints(self, model: mujoco.MjModel) -> None:
        """Each object's movable concept joints and their qpos addresses in ``model``."""
        self._joints = {}
        for name, exported, prefix in zip(self.names, self.scene.models, self.scene.prefixes):
            inst = self._initial[name]
            self._joints[name] = {
                j.source: int(model.joint(prefix + j.name).qposadr[0])
                for j in exported.joints
                if j.kind != "fixed" and j.source in inst.concept.joint_index
            }

    @abstractmethod
    def _state(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        """The compiled model and its live data (the acting world's)."""

    def joints(self, obj: str) -> dict[str, float]:
        """The measured value of every joint of object ``obj`` (concept joint names)."""
        qpos = self._state()[1].qpos
        return {j: float(qpos[a]) for j, a in self._addresses(obj).items()}

    def q(self, obj: str, joint: str) -> float:
        """The measured value of one joint of object ``obj``."""
        addresses = self._addresses(obj)
        if joint not in addresses:
            raise MultiWorldError(
                f"object {obj!r} has no movable joint {joint!r}; it has {sorted(addresses)}"
            )
        return float(self._state()[1].qpos[addresses[joint]])

    def instance(self, obj: str) -> Instance:
        """Object ``obj`` as an instance at its world pose with its MEASURED joint values: what
        the runtime ranks grasps and plans paths on."""
        self._addresses(obj)
        return self._initial[obj].with_joints(self.joints(obj))

    def render(self) -> Frame:
        """The scene camera's RGB, depth and segmentation of the world as it is now."""
        return self.scene.render(*self._state())

    def _addresses(self, obj: str) -> dict[str, int]:
        if obj not in self._joints:
            raise MultiWorldError(f"no object {obj!r} in this world; it has {list(self.names)}")
        return self._joints[obj]


class MultiWorld(Room):
    """Several posed instances (world poses, as ``place`` gives) and the flying hand."""

    def __init__(
        self,
        objects: Sequence[tuple[str, Instance]],
        gripper: Gripper | None = None,
        camera: Camera | None = None,
        impedance: Impedance | None = None,
    ):
        self._set_objects(objects, camera)
        self.gripper = gripper or Gripper.load("panda")
        park = np.eye(4)
        park[:3, 3] = PARK
        park[:3, :3] = np.diag([1.0, -1.0, -1.0])  # pointing down
        hand_xml, hand = _hand_spec(self.gripper, park)
        model, data = self.scene.compile(extra=[(mujoco.MjSpec.from_string(hand_xml), HAND)])
        hand = replace(
            hand,
            body=HAND + hand.body,
            fingers=tuple(HAND + f for f in hand.fingers),
            actuators=tuple(HAND + a for a in hand.actuators),
        )
        free = model.joint(HAND + "hand_free")
        dof = int(free.dofadr[0])
        model.dof_damping[dof : dof + 3] = LINEAR_DAMPING
        model.dof_damping[dof + 3 : dof + 6] = ANGULAR_DAMPING
        model.dof_armature[dof + 3 : dof + 6] += ANGULAR_ARMATURE
        self._index_joints(model)
        body = model.body(hand.body).id
        self.world = World(model, data, hand, {}, body, impedance or Impedance())
        self.world.set_fingers(0.0, at_once=True)
        mujoco.mj_forward(model, data)

    # -- reading
    @property
    def time(self) -> float:
        return self.world.time

    def _state(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        return self.world.model, self.world.data

    # -- acting
    def act(
        self,
        obj: str,
        action: str,
        joint: str,
        sign: float,
        option: Option,
        goal: float | None = None,
        seconds: float = 20.0,
        inst: Instance | None = None,
    ) -> Act:
        """Carry out ``action`` (moving ``joint`` the ``sign`` way) on ``obj`` with ``option``
        (from ``instance(obj).rank``) until the joint reaches ``goal`` (default: the episode's
        open or close goal), in at most ``seconds`` simulated seconds; the hand then lets go and
        backs off. The world keeps the result. ``inst``: the agent's model of the object, posed
        and at the measured joint values (default: the true one, ``instance(obj)``)."""
        if sign not in (1.0, -1.0):
            raise ParameterError(f"sign must be +1 (opening) or -1 (closing), got {sign!r}")
        inst = self.instance(obj) if inst is None else inst
        q0 = self.q(obj, joint)
        view = replace(self.world, joint_qpos=self._addresses(obj))
        began = self.world.time
        out = execute(
            inst,
            TaskAction(action, joint, sign),
            option,
            self.gripper,
            seconds,
            goal=goal,
            world=view,
        )
        self.world.finger_goal = view.finger_goal
        self.world.place_hand(_parked(self.world.hand_pose()))
        return Act(obj, joint, q0, self.q(obj, joint), out, self.world.time - began)


def _parked(pose: np.ndarray) -> np.ndarray:
    """The hand's pose lifted to the parking height: out of every object's way."""
    out = pose.copy()
    out[:3, 3] = PARK
    return out


def _physical(text: str) -> str:
    """An exported object's MJCF made physical as ``World.build`` makes it (module docstring)."""
    root = ET.fromstring(text)
    for body in root.iter("body"):
        body.set("gravcomp", "1")
    for joint in root.iter("joint"):
        joint.set("frictionloss", str(FRICTION))
    for geom in root.iter("geom"):
        if geom.get("contype") == "0" and geom.get("conaffinity") == "0":
            continue  # a visual piece
        geom.set("contype", str(OBJECT_GROUP))
        geom.set("conaffinity", str(HAND_GROUP))
    return ET.tostring(root, encoding="unicode")


def _hand_spec(gripper: Gripper, pose: np.ndarray) -> tuple[str, HandSpec]:
    """The flying hand as a stand-alone MJCF document (attached to the scene's world)."""
    spec, assets, body, actuators = build_hand(gripper, pose, GRASP_FORCE)
    root = ET.Element("mujoco", model="hand")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    if assets:
        ET.SubElement(root, "asset").extend(assets)
    ET.SubElement(root, "worldbody").append(body)
    if actuators:
        ET.SubElement(root, "actuator").extend(actuators)
    for mesh in root.iter("mesh"):
        mesh.set("file", str(Path(mesh.get("file", "")).resolve()))
    return ET.tostring(root, encoding="unicode"), spec
