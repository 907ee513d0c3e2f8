"""The full Panda in MuJoCo, on a base beside a concept instance, driven by joint torques.

The arm's chain comes from the same file the robot layer plans with (example-robot-data's
``panda.urdf``): every link's inertial and its collision mesh (STL, which MuJoCo loads as is;
it collides with a mesh's convex hull, which for the Panda's links is what their shapes nearly
are), every joint's origin, axis, range and torque limit (87 N m on joints 1-4, 12 N m on 5-7).
The URDF's visual meshes are COLLADA, which MuJoCo cannot read, so the collision meshes are the
visuals too. The hand is the flying hand's (``grace_dsl.sim.hand``: ``hand.stl``, the finger
boxes, pads at 70 N) fixed to the flange where ``panda_hand_tcp`` is, so both agents touch the
object with the same fingers.

Each joint carries a motor's reflected inertia (``ARMATURE``, 0.1 kg m^2 as in published
Panda models) and a little viscous damping; its torque motor is capped at the URDF's effort
limit. Gravity is compensated on the arm's bodies (the real arm's controller does the same
from its dynamic model). The arm touches the object and nothing else: self-collision is the
planner's business (``grace_dsl.robot.collision``), and the MuJoCo bodies of a serial chain
overlap at their joints anyway.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from grace_dsl.export.mjcf import write_mjcf
from grace_dsl.export.model import FRICTION, build_model
from grace_dsl.robot.model import robot_data_file
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.hand import (
    GRASP_FORCE,
    HAND_GROUP,
    OBJECT_GROUP,
    HandSpec,
    build_hand,
    quat_wxyz,
)

TIMESTEP = 0.002  # s
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
ARM_LINKS = tuple(f"panda_link{i}" for i in range(0, 8))
ARMATURE = 0.1  # kg m^2: the joint motors' reflected inertia
JOINT_DAMPING = 0.5  # N m s/rad of viscous friction per joint
# panda_link8 (the flange) -> panda_hand_tcp: 107 mm, -45 degrees about z, then 103.4 mm
FLANGE = 0.107
TCP = 0.1034
HAND_TURN = -math.pi / 4
FINGER_SPEED = 0.1  # m/s per finger (panda.urdf's finger velocity limit is 0.2 for both)


@dataclass(frozen=True)
class ArmJoint:
    """One revolute joint of the URDF chain: its parent-frame origin, axis and limits."""

    name: str
    parent: str
    child: str
    origin: np.ndarray  # 4x4, parent link frame -> joint frame
    axis: np.ndarray
    lower: float
    upper: float
    effort: float


@dataclass(frozen=True)
class ArmLink:
    """A link's inertial (in its frame) and collision mesh file."""

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray  # ixx iyy izz ixy ixz iyz
    mesh: Path | None


@dataclass(frozen=True)
class PandaChain:
    """The arm's links 0-7 and joints 1-7 read from the URDF, in order from the base."""

    links: tuple[ArmLink, ...]
    joints: tuple[ArmJoint, ...]

    @property
    def effort(self) -> np.ndarray:
        return np.array([j.effort for j in self.joints])


@lru_cache(maxsize=1)
def panda_chain() -> PandaChain:
    """The Panda's arm chain from example-robot-data's ``panda.urdf`` (read once)."""
    urdf = robot_data_file("panda_description/urdf/panda.urdf")
    root = ET.parse(urdf).getroot()
    meshes = urdf.parents[1] / "meshes" / "collision"
    links = []
    for name in ARM_LINKS:
        el = root.find(f"link[@name='{name}']")
        if el is None:
            raise ParameterError(f"{urdf} has no link {name}: not the Panda description")
        inertial = el.find("inertial")
        assert inertial is not None
        mass = float(_attr(inertial, "mass", "value"))
        com = _floats(_attr(inertial, "origin", "xyz"))
        i = inertial.find("inertia")
        assert i is not None
        inertia = np.array(
            [float(i.get(k, "0")) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
        )
        mesh_el = el.find("collision/geometry/mesh")
        mesh = meshes / Path(mesh_el.get("filename", "")).name if mesh_el is not None else None
        links.append(ArmLink(name, mass, com, inertia, mesh))
    joints = []
    for name in ARM_JOINTS:
        el = root.find(f"joint[@name='{name}']")
        if el is None:
            raise ParameterError(f"{urdf} has no joint {name}: not the Panda description")
        origin = _origin(_floats(_attr(el, "origin", "xyz")), _floats(_attr(el, "origin", "rpy")))
        joints.append(
            ArmJoint(
                name,
                _attr(el, "parent", "link"),
                _attr(el, "child", "link"),
                origin,
                _floats(_attr(el, "axis", "xyz")),
                float(_attr(el, "limit", "lower")),
                float(_attr(el, "limit", "upper")),
                float(_attr(el, "limit", "effort")),
            )
        )
    return PandaChain(tuple(links), tuple(joints))


def flange_to_tcp() -> np.ndarray:
    """panda_link7's frame -> the gripper frame (``panda_hand_tcp``), as in panda.urdf."""
    c, s = math.cos(HAND_TURN), math.sin(HAND_TURN)
    pose = np.eye(4)
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[2, 3] = FLANGE + TCP
    return pose


def arm_body(
    base: np.ndarray, gripper: Gripper, grasp_force: float = GRASP_FORCE
) -> tuple[HandSpec, list[ET.Element], ET.Element, list[ET.Element]]:
    """The arm's MJCF: (hand spec, mesh assets, the base body at ``base``, actuators: the seven
    joint motors, then the fingers' servos)."""
    chain = panda_chain()
    assets = [
        ET.Element("mesh", name=f"arm_{link.name}", file=str(link.mesh))
        for link in chain.links
        if link.mesh is not None
    ]
    root = ET.Element("body", name="panda_link0", pos=_vec(base[:3, 3]), quat=_vec(quat_wxyz(base)))
    _link(root, chain.links[0])
    parent = root
    actuators = []
    for joint, link in zip(chain.joints, chain.links[1:]):
        body = ET.SubElement(
            parent,
            "body",
            name=link.name,
            pos=_vec(joint.origin[:3, 3]),
            quat=_vec(quat_wxyz(joint.origin)),
        )
        body.set("gravcomp", "1")
        ET.SubElement(
            body,
            "joint",
            name=joint.name,
            type="hinge",
            axis=_vec(joint.axis),
            range=f"{joint.lower:.9g} {joint.upper:.9g}",
            limited="true",
            armature=_vec([ARMATURE]),
            damping=_vec([JOINT_DAMPING]),
        )
        _link(body, link)
        actuators.append(
            ET.Element(
                "motor",
                name=f"{joint.name}_motor",
                joint=joint.name,
                ctrlrange=f"{-joint.effort:g} {joint.effort:g}",
                ctrllimited="true",
            )
        )
        parent = body
    spec, hand_assets, hand, finger_servos = build_hand(gripper, flange_to_tcp(), grasp_force)
    free = hand.find("freejoint")
    if free is not None:
        hand.remove(free)
    parent.append(hand)
    return spec, assets + hand_assets, root, actuators + finger_servos


def _link(body: ET.Element, link: ArmLink) -> None:
    ixx, iyy, izz, ixy, ixz, iyz = link.inertia
    ET.SubElement(
        body,
        "inertial",
        pos=_vec(link.com),
        mass=_vec([max(link.mass, 1e-3)]),
        fullinertia=_vec([ixx, iyy, izz, ixy, ixz, iyz]),
    )
    if link.mesh is not None:
        geom = ET.SubElement(body, "geom", name=f"{link.name}_collision", type="mesh")
        geom.set("mesh", f"arm_{link.name}")
        geom.set("contype", str(HAND_GROUP))
        geom.set("conaffinity", str(OBJECT_GROUP))
        geom.set("rgba", "0.92 0.92 0.95 1")


@dataclass
class ArmWorld:
    """A compiled MuJoCo model with the object and the arm, and the names an episode drives."""

    model: mujoco.MjModel
    data: mujoco.MjData
    hand: HandSpec
    base: np.ndarray
    joint_qpos: dict[str, int]  # concept joint -> qpos address
    arm_qpos: np.ndarray  # the 7 arm joints' qpos addresses
    arm_dof: np.ndarray  # their dof addresses
    arm_ctrl: np.ndarray  # their motors' actuator ids
    effort: np.ndarray  # N m, the motors' caps
    hand_body: int
    arm_geoms: frozenset[int]  # the arm's links' geoms (not the hand or fingers)
    object_geoms: frozenset[int]
    finger_goal: float = 0.0

    @staticmethod
    def build(
        inst: Instance, base: np.ndarray, q: np.ndarray, gripper: Gripper | None = None
    ) -> ArmWorld:
        """The world of ``inst`` (joints at its values, parts balanced against gravity as for
        the flying hand) with the arm's base at ``base`` (world pose) and its joints at ``q``."""
        gripper = gripper or Gripper.panda()
        root = _object_root(inst)
        spec, assets, body, actuators = arm_body(np.asarray(base, float), gripper)
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
        ET.SubElement(root, "actuator").extend(actuators)
        model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
        data = mujoco.MjData(model)
        exported = build_model(inst)
        addresses = {}
        for j in exported.joints:
            if j.kind != "fixed" and j.source in inst.concept.joint_index:
                adr = int(model.joint(j.name).qposadr[0])
                addresses[j.source] = adr
                data.qpos[adr] = inst.joints[j.source]
        qadr = np.array([model.joint(n).qposadr[0] for n in ARM_JOINTS])
        dadr = np.array([model.joint(n).dofadr[0] for n in ARM_JOINTS])
        data.qpos[qadr] = np.asarray(q, float)
        arm_bodies = {model.body(n).id for n in ARM_LINKS}
        hand_bodies = {
            i for i in range(model.nbody) if model.body(i).name.startswith(("hand", "finger_"))
        }
        ours = arm_bodies | hand_bodies
        w = ArmWorld(
            model,
            data,
            spec,
            np.asarray(base, float),
            addresses,
            qadr,
            dadr,
            np.array([model.actuator(f"{n}_motor").id for n in ARM_JOINTS]),
            panda_chain().effort,
            model.body("hand").id,
            frozenset(g for g in range(model.ngeom) if model.geom_bodyid[g] in arm_bodies),
            frozenset(
                g
                for g in range(model.ngeom)
                if model.geom_bodyid[g] not in ours and model.geom_bodyid[g] != 0
            ),
        )
        w.set_fingers(gripper.max_width, at_once=True)
        for name in spec.fingers:
            data.qpos[model.joint(name).qposadr[0]] = w.finger_goal
        mujoco.mj_forward(model, data)
        return w

    # -- reading
    @property
    def time(self) -> float:
        return float(self.data.time)

    def q(self, joint: str) -> float:
        """The measured value of a concept joint."""
        return float(self.data.qpos[self.joint_qpos[joint]])

    def arm_q(self) -> np.ndarray:
        return self.data.qpos[self.arm_qpos].copy()

    def arm_dq(self) -> np.ndarray:
        return self.data.qvel[self.arm_dof].copy()

    def hand_pose(self) -> np.ndarray:
        """The gripper frame's measured world pose."""
        pose = np.eye(4)
        pose[:3, :3] = self.data.xmat[self.hand_body].reshape(3, 3)
        pose[:3, 3] = self.data.xpos[self.hand_body]
        return pose

    def jacobian(self) -> np.ndarray:
        """(6, 7): world linear and angular velocity of the gripper frame per arm joint."""
        jp = np.zeros((3, self.model.nv))
        jr = np.zeros((3, self.model.nv))
        mujoco.mj_jacBody(self.model, self.data, jp, jr, self.hand_body)
        return np.vstack([jp[:, self.arm_dof], jr[:, self.arm_dof]])

    def opening(self) -> float:
        """The measured distance between the pads' inner faces."""
        return float(sum(self.data.qpos[self.model.joint(j).qposadr[0]] for j in self.hand.fingers))

    def arm_contact(self) -> bool:
        """An arm link (not the hand) touches the object now."""
        n = self.data.ncon
        if n == 0:
            return False
        pairs = self.data.contact.geom[:n]  # (n, 2), without a Python object per contact
        arm, obj = self._masks()
        a, b = pairs[:, 0], pairs[:, 1]
        return bool(np.any((arm[a] & obj[b]) | (arm[b] & obj[a])))

    def _masks(self) -> tuple[np.ndarray, np.ndarray]:
        """``arm_geoms`` and ``object_geoms`` as boolean masks over the model's geoms."""
        if "_geom_masks" not in self.__dict__:
            arm = np.zeros(self.model.ngeom, bool)
            obj = np.zeros(self.model.ngeom, bool)
            arm[list(self.arm_geoms)] = True
            obj[list(self.object_geoms)] = True
            object.__setattr__(self, "_geom_masks", (arm, obj))
        masks: tuple[np.ndarray, np.ndarray] = self.__dict__["_geom_masks"]
        return masks

    def unstable(self) -> bool:
        """The state blew up (MuJoCo flags a bad acceleration and resets it)."""
        return bool(self.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number) or not all(
            map(math.isfinite, self.data.qpos)
        )

    # -- driving
    def set_fingers(self, width: float, at_once: bool = False) -> None:
        """Command the pads ``width`` apart (force capped), at the real finger speed unless
        ``at_once``."""
        self.finger_goal = min(max(width / 2, 0.0), self.hand.finger_travel)
        if at_once:
            for name in self.hand.actuators:
                self.data.ctrl[self.model.actuator(name).id] = self.finger_goal

    def step(self, torque: np.ndarray) -> None:
        """One physics step with the arm's motors at ``torque`` (capped at their limits)."""
        d = self.data
        step = FINGER_SPEED * self.model.opt.timestep
        for name in self.hand.actuators:
            i = self.model.actuator(name).id
            now = float(d.ctrl[i])
            d.ctrl[i] = now + max(-step, min(step, self.finger_goal - now))
        d.ctrl[self.arm_ctrl] = np.clip(torque, -self.effort, self.effort)
        mujoco.mj_step(self.model, d)


def _object_root(inst: Instance) -> ET.Element:
    """The instance's exported MJCF, prepared as the flying hand's world prepares it: no
    keyframe, parts balanced against gravity with the base hinge friction, collision geoms in
    the object's contact group."""
    root = ET.fromstring(write_mjcf(build_model(inst)))
    for key in root.findall("keyframe"):
        root.remove(key)
    for body in root.iter("body"):
        body.set("gravcomp", "1")
    for joint in root.iter("joint"):
        joint.set("frictionloss", str(FRICTION))
    for geom in root.iter("geom"):
        if geom.get("contype") == "0" and geom.get("conaffinity") == "0":
            continue
        geom.set("contype", str(OBJECT_GROUP))
        geom.set("conaffinity", str(HAND_GROUP))
    return root


def _origin(xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    """URDF's origin: translation ``xyz``, rotation Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    pose = np.eye(4)
    pose[:3, :3] = rz @ ry @ rx
    pose[:3, 3] = xyz
    return pose


def _attr(el: ET.Element, child: str, key: str) -> str:
    found = el.find(child)
    value = found.get(key) if found is not None else None
    if value is None:
        raise ParameterError(f"panda.urdf: <{el.get('name')}> has no {child} {key}")
    return value


def _floats(text: str) -> np.ndarray:
    return np.array([float(x) for x in text.split()])


def _vec(v: object) -> str:
    return " ".join(f"{float(x):.9g}" for x in np.asarray(v, float).ravel())
