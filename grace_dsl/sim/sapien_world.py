"""One concept instance and one flying hand in SAPIEN 3's PhysX, the second physics engine.

The same world as ``grace_dsl.sim.world`` (MuJoCo) behind the same small interface the episode
drives (``place_hand``, ``step``, ``q``, ``hand_pose``, ``set_fingers``, ``opening``, ...), so an
episode's draws, option, controller and success criteria are the same on both engines and only
the physics differs. The scene is a PhysX CPU system alone, with no render system: SAPIEN's
physics needs no GPU then, and the object comes from the project's URDF export written without
its visual elements (a scene without a renderer refuses them), its collision elements the
export's convex pieces.

What MuJoCo expresses in its model is rebuilt with PhysX's means:

- The hand is a free-floating articulation whose root frame IS the gripper frame, its weight
  off, pulled by the same capped Cartesian spring (``Impedance``) applied at the gripper origin;
  the free joint's damping becomes the links' velocity damping (PhysX integrates it implicitly).
  The fingers are prismatic joints with a position drive whose force is capped at 70 N.
- The object's joints get the export's armature; a friction loss (Coulomb friction, MuJoCo's
  ``frictionloss``) becomes a velocity drive towards rest whose force is capped at the friction
  (saturated above ``STICK_SPEED``), and the export's viscous damping is applied as a joint force.
- Balanced as in MuJoCo: the part the driven joint moves weighs nothing and keeps the export's
  base friction only; the other parts keep their weight and the export's holding friction.
- Collision groups: the hand touches the object, neither touches itself.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.export.model import FRICTION, ExportModel, build_model
from grace_dsl.export.urdf import write_urdf
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import Gripper, HandBox
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.control import Impedance, quat_of
from grace_dsl.sim.hand import (
    FINGER_KP,
    FINGER_MASS,
    GRASP_FORCE,
    PANDA_HAND_Z,
    PANDA_INERTIA,
    PANDA_MASS,
    HandSpec,
    panda_meshes,
)
from grace_dsl.sim.world import (
    ANGULAR_ARMATURE,
    ANGULAR_DAMPING,
    FINGER_SPEED,
    LINEAR_DAMPING,
    TIMESTEP,
)

HAND_GROUP, OBJECT_GROUP = 1, 2  # PhysX contact type / affinity bits, as the MJCF's contype
PAD_FRICTION = 1.2  # rubber pads (MuJoCo's sliding friction of the pads)
OBJECT_FRICTION = 1.0  # MuJoCo's default sliding friction of the object's geoms
FINGER_DAMPING = 40.0  # N s/m on each finger joint (as the MJCF's finger slide)
FINGER_ARMATURE = 0.1  # kg, ibid.
STICK_SPEED = 1e-3  # m/s or rad/s: below this a joint's friction drive acts as viscous damping
POSITION_ITERATIONS = 20  # PhysX solver iterations per step (its default of 10 lets pads slip)
MAX_SPEED = 50.0  # m/s: a hand faster than this means the state blew up


def available() -> bool:
    """SAPIEN 3 is installed (the optional ``sapien`` extra)."""
    try:
        import sapien  # noqa: F401
    except ImportError:
        return False
    return True


def _sapien() -> Any:
    try:
        import sapien
    except ImportError as exc:
        raise ParameterError(
            "engine 'sapien' needs SAPIEN 3: pip install -e '.[sapien]' (or sapien==3.0.3)"
        ) from exc
    return sapien


@dataclass
class SapienWorld:
    """A PhysX scene with the object's and the hand's articulations, and the names an episode
    reads and drives (the interface of ``grace_dsl.sim.world.World``)."""

    scene: Any
    obj: Any  # PhysxArticulation of the object (root fixed)
    hand_art: Any  # PhysxArticulation of the hand (root free)
    hand: HandSpec
    joint_index: dict[str, int]  # concept joint name -> index in the object's qpos
    impedance: Impedance
    damping: np.ndarray  # N m s/rad or N s/m per object dof: the export's viscous damping
    finger_goal: float = 0.0
    trace_every: int = 0  # no replay from SAPIEN: the episode refuses a trace on this engine
    trace: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    _time: float = 0.0
    _finger_cmd: float = 0.0
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
    ) -> SapienWorld:
        """The world of ``inst`` (joints at its values) with the hand at ``hand_pose``;
        ``balanced`` and ``driven`` as ``World.build``'s (the object's own bodies never
        collide with each other here)."""
        sapien = _sapien()
        physx = sapien.physx
        scene = sapien.Scene([physx.PhysxCpuSystem()])
        scene.timestep = TIMESTEP
        exported = build_model(inst)
        obj = _load_object(scene, exported)
        index = {j.name: i for i, j in enumerate(obj.active_joints)}
        by_name = {j.name: j for j in exported.joints if j.kind != "fixed"}
        moved = {j.name for j in exported.joints if driven in (None, j.source)}
        links = {link.name: link for link in obj.links}
        damping = np.zeros(obj.dof)
        for joint in obj.active_joints:
            source = by_name[joint.name]
            joint.armature = np.array([source.armature], dtype=np.float32)
            friction = FRICTION if balanced and source.name in moved else source.friction
            joint.set_drive_properties(0.0, friction / STICK_SPEED, friction, "force")
            joint.set_drive_velocity_target(np.zeros(1, dtype=np.float32))
            damping[index[joint.name]] = source.damping
        if balanced:
            for name in _moved_links(exported, {j for j in moved if j in by_name}):
                links[name].disable_gravity = True
        qpos = np.zeros(obj.dof, dtype=np.float32)
        addresses: dict[str, int] = {}
        for j in exported.joints:
            if j.kind != "fixed" and j.source in inst.concept.joint_index:
                addresses[j.source] = index[j.name]
                qpos[index[j.name]] = inst.joints[j.source]
        obj.set_qpos(qpos)
        obj.set_solver_position_iterations(POSITION_ITERATIONS)
        hand_art, spec = _build_hand(scene, gripper)
        world = SapienWorld(
            scene, obj, hand_art, spec, addresses, impedance or Impedance(), damping
        )
        world.place_hand(hand_pose)
        physx.clear_cache()  # the mesh cache keeps every episode's meshes otherwise
        return world

    # -- reading
    @property
    def time(self) -> float:
        return self._time

    @property
    def timestep(self) -> float:
        return TIMESTEP

    def q(self, joint: str) -> float:
        """The measured value of a concept joint."""
        return float(self.obj.qpos[self.joint_index[joint]])

    def qdot(self, joint: str) -> float:
        """The measured velocity of a concept joint."""
        return float(self.obj.qvel[self.joint_index[joint]])

    def hand_pose(self) -> np.ndarray:
        """The hand's measured world pose (the gripper frame)."""
        return np.asarray(self.hand_art.root_pose.to_transformation_matrix(), dtype=float)

    def opening(self) -> float:
        """The measured distance between the pads' inner faces."""
        return float(np.sum(self.hand_art.qpos)) if self.hand.fingers else 0.0

    def unstable(self) -> bool:
        """The state blew up: a non-finite value, or the hand flung off."""
        values = np.concatenate([self.obj.qpos, self.hand_art.qpos, self.hand_pose()[:3, 3]])
        speed = float(np.linalg.norm(self.hand_art.root_linear_velocity))
        return not bool(np.all(np.isfinite(values))) or not speed < MAX_SPEED

    # -- driving
    def place_hand(self, pose: np.ndarray) -> None:
        """Put the hand at ``pose`` at rest with its fingers shut."""
        sapien = _sapien()
        hand = self.hand_art
        hand.set_root_pose(sapien.Pose(np.asarray(pose, dtype=np.float32)))
        hand.set_root_linear_velocity(np.zeros(3, dtype=np.float32))
        hand.set_root_angular_velocity(np.zeros(3, dtype=np.float32))
        if hand.dof:
            hand.set_qpos(np.zeros(hand.dof, dtype=np.float32))
            hand.set_qvel(np.zeros(hand.dof, dtype=np.float32))
        self._target = self._target_quat = None
        self.set_fingers(0.0, at_once=True)

    def set_fingers(self, width: float, at_once: bool = False) -> None:
        """Command the pads ``width`` apart (each finger half of it; force capped); the command
        moves at the real finger speed unless ``at_once``."""
        self.finger_goal = min(max(width / 2, 0.0), self.hand.finger_travel)
        if at_once:
            self._finger_cmd = self.finger_goal
            self._drive_fingers()

    def _drive_fingers(self) -> None:
        target = np.array([self._finger_cmd], dtype=np.float32)
        for joint in self.hand_art.active_joints:
            joint.set_drive_target(target)

    def step(self, target: np.ndarray) -> None:
        """One physics step with the impedance wrench towards ``target`` at the gripper origin."""
        if target is not self._target or self._target_quat is None:
            self._target, self._target_quat = target, quat_of(target)
        if self._finger_cmd != self.finger_goal:
            step = FINGER_SPEED * TIMESTEP
            self._finger_cmd += max(-step, min(step, self.finger_goal - self._finger_cmd))
            self._drive_fingers()
        pose = self.hand_pose()
        pos = pose[:3, 3]
        w = self.impedance.wrench_at(pos, pose[:3, :3], target[:3, 3], self._target_quat)
        root = self.hand_art.root
        root.add_force_at_point(w[:3].astype(np.float32), pos.astype(np.float32))
        root.add_force_torque(np.zeros(3, dtype=np.float32), w[3:].astype(np.float32))
        if self.obj.dof:
            self.obj.set_qf((-self.damping * self.obj.qvel).astype(np.float32))
        self.scene.step()
        self._time += TIMESTEP


def _load_object(scene: Any, exported: ExportModel) -> Any:
    """The exported model through SAPIEN's URDF loader (collision elements only), its root
    fixed, every shape in the object's collision group."""
    with tempfile.TemporaryDirectory(prefix="grace-sapien-") as folder:
        path = Path(folder) / "object.urdf"
        write_urdf(exported, path, visual=False)
        loader = scene.create_urdf_loader()
        loader.fix_root_link = True
        loader.set_material(OBJECT_FRICTION, OBJECT_FRICTION, 0.0)
        obj = loader.load(str(path))
    for link in obj.links:
        for shape in link.collision_shapes:
            shape.set_collision_groups([OBJECT_GROUP, HAND_GROUP, 0, 0])
    return obj


def _moved_links(exported: ExportModel, joints: set[str]) -> set[str]:
    """The exported links that one of ``joints`` moves (its child and below)."""
    out: set[str] = set()
    stack = [j.child for j in exported.joints if j.name in joints]
    while stack:
        link = stack.pop()
        out.add(link)
        stack += [j.child for j in exported.children(link)]
    return out


def _build_hand(scene: Any, gripper: Gripper) -> tuple[Any, HandSpec]:
    """The flying hand as a free articulation: the palm (the Panda's ``hand.stl`` hull, or the
    description's boxes) and two fingers on prismatic joints with capped position drives."""
    sapien = _sapien()
    physx = sapien.physx
    builder = scene.create_articulation_builder()
    palm = builder.create_link_builder()
    palm.set_name("hand")
    palm.collision_groups = [HAND_GROUP, OBJECT_GROUP, 0, 0]
    inertia = np.asarray(PANDA_INERTIA, float)
    inertia = inertia + ANGULAR_ARMATURE  # the rotor-like inertia MuJoCo adds to the rotation
    if gripper.name == "panda":
        com = (-0.01, 0.0, PANDA_HAND_Z + 0.03)
        mesh = str(panda_meshes() / "hand.stl")
        palm.add_convex_collision_from_file(mesh, sapien.Pose([0.0, 0.0, PANDA_HAND_Z]))
    else:
        com = (0.0, 0.0, -0.08)
        for box in gripper.palm:
            _add_box(palm, box, None)
    palm.set_mass_and_inertia(PANDA_MASS, sapien.Pose(com), inertia)
    pads = physx.PhysxMaterial(PAD_FRICTION, PAD_FRICTION, 0.0)
    travel = gripper.max_width / 2
    movable = gripper.can_close and travel > 0
    names: list[str] = []
    for side, label in ((1.0, "left"), (-1.0, "right")):
        link = palm
        if movable:
            link = builder.create_link_builder(palm)
            link.set_name(f"finger_{label}")
            name = f"finger_{label}_slide"
            link.set_joint_name(name)
            turn = sapien.Pose(q=_about_z(side * math.pi / 2))  # the joint's x along +-y
            link.set_joint_properties("prismatic", [[0.0, travel]], turn, turn)
            link.collision_groups = [HAND_GROUP, OBJECT_GROUP, 0, 0]
            link.set_mass_and_inertia(
                FINGER_MASS, sapien.Pose([0.0, side * 0.01, -0.03]), (2.4e-6, 2.4e-6, 7.5e-7)
            )
            names.append(name)
        pad = HandBox(
            "pad",
            (0.0, side * gripper.finger_thickness / 2, -gripper.finger_length / 2),
            (gripper.finger_width / 2, gripper.finger_thickness / 2, gripper.finger_length / 2),
        )
        _add_box(link, pad, pads)
        for block in gripper.fingers:
            _add_box(link, block if side > 0 else block.mirrored(), None)
    hand = builder.build(fix_root_link=False)
    hand.set_name("hand")
    mass = PANDA_MASS + FINGER_MASS * len(names)
    for link in hand.links:
        link.disable_gravity = True
        link.linear_damping = LINEAR_DAMPING / mass
        link.angular_damping = ANGULAR_DAMPING / float(np.min(inertia))
    for joint in hand.active_joints:
        joint.set_drive_properties(FINGER_KP, FINGER_DAMPING, GRASP_FORCE, "force")
        joint.armature = np.array([FINGER_ARMATURE], dtype=np.float32)
    hand.set_solver_position_iterations(POSITION_ITERATIONS)
    spec = HandSpec(
        gripper,
        fingers=tuple(names),
        actuators=tuple(names),
        finger_travel=travel if names else 0.0,
        grasp_force=GRASP_FORCE,
    )
    return hand, spec


def _add_box(link: Any, box: HandBox, material: Any) -> None:
    import sapien

    pose = box.pose()
    link.add_box_collision(
        sapien.Pose(pose[:3, 3].astype(np.float32), quat_of(pose).astype(np.float32)),
        half_size=tuple(float(x) for x in box.half_extents),
        material=material,
    )


def _about_z(angle: float) -> np.ndarray:
    """The (w, x, y, z) quaternion of a turn by ``angle`` about z."""
    return np.array([math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)], dtype=np.float32)
