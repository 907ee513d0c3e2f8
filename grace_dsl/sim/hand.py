"""A flying hand in MuJoCo, built from a ``Gripper`` description.

The hand is one free body whose frame IS the gripper frame (DESIGN.md §6: origin between the
fingertips, +z the approach, +y the closing direction), so a grasp pose from the runtime is
directly the body's target. It floats: gravity is compensated and an impedance wrench
(``grace_dsl.sim.control``) drives its six degrees of freedom; its free joint carries damping,
which MuJoCo integrates implicitly, so stiff gains stay stable at a 2 ms step.

Two fingers slide along ±y under position actuators whose force is capped: the Panda hand's
70 N continuous grasp force (Franka's datasheet) by default. The Panda's geometry is the real
one, from example-robot-data's Panda description: the hand's collision mesh ``hand.stl`` and the
finger collision boxes of ``panda.urdf`` (the boxes ``grace_dsl/hands/panda.toml`` cites), with
``finger.stl`` as each finger's visual. Other hands are built from their description's boxes.
A hand that cannot close (``max_width == 0``) gets no finger joints.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import Gripper, HandBox

GRASP_FORCE = 70.0  # N, the Panda hand's continuous grasp force (Franka datasheet)
PANDA_HAND_Z = -0.1129  # panda_hand's origin in the gripper frame (hands/panda.toml)
PANDA_FINGER_Z = 0.0584  # panda_finger_joint1/2 origin in panda_hand
PANDA_MASS = 0.73  # kg, panda_hand's inertial in panda.urdf
PANDA_INERTIA = (0.001, 0.0025, 0.0017)  # kg m^2, ibid.
FINGER_MASS = 0.015  # kg, panda_leftfinger's inertial
PAD_FRICTION = "1.2 0.02 0.0001"  # rubber pads: sliding, torsional, rolling
# stiff pad contacts: 70 N on a 4 mm bar must not sink the pads through it (MuJoCo's default
# 20 ms time constant lets them in by millimetres); 4 ms is twice the 2 ms step
PAD_SOLREF = "0.004 1"
PAD_SOLIMP = "0.95 0.99 0.001"
HAND_GROUP, OBJECT_GROUP = 1, 2  # contype bits: the hand touches the object, not itself
FINGER_KP = 4000.0  # N/m of the finger position servo (saturates at the force cap)


@dataclass(frozen=True)
class HandSpec:
    """What the scene needs to know about the hand it was given: names in the MJCF and limits."""

    gripper: Gripper
    body: str = "hand"
    fingers: tuple[str, ...] = ()  # finger joint names, +y finger first
    actuators: tuple[str, ...] = ()  # finger actuator names, same order
    finger_travel: float = 0.0  # each finger's stroke, metres (half the opening)
    grasp_force: float = GRASP_FORCE


def panda_meshes() -> Path:
    """The Panda description's collision mesh folder (example-robot-data, a pinocchio dep)."""
    import sys

    for root in (Path(sys.prefix), *map(Path, sys.path)):
        for base in (root / "share", root / "cmeel.prefix" / "share"):
            d = base / "example-robot-data/robots/panda_description/meshes/collision"
            if (d / "hand.stl").is_file():
                return d
    raise ParameterError(
        "the Panda hand's meshes (example-robot-data panda_description) are not installed; "
        "install the project with its pinocchio dependency (pip install -e .)"
    )


def build_hand(
    gripper: Gripper, pose: np.ndarray, grasp_force: float = GRASP_FORCE
) -> tuple[HandSpec, list[ET.Element], ET.Element, list[ET.Element]]:
    """The hand's MJCF pieces: (spec, mesh assets, the body at ``pose``, finger actuators)."""
    panda = gripper.name == "panda"
    assets: list[ET.Element] = []
    body = ET.Element("body", name="hand", pos=_vec(pose[:3, 3]), quat=_vec(quat_wxyz(pose)))
    body.set("gravcomp", "1")
    ET.SubElement(body, "freejoint", name="hand_free")
    if panda:
        meshes = panda_meshes()
        for name in ("hand", "finger"):
            assets.append(
                ET.Element("mesh", name=f"panda_{name}", file=str(meshes / f"{name}.stl"))
            )
        ET.SubElement(
            body,
            "inertial",
            pos=f"-0.01 0 {PANDA_HAND_Z + 0.03:g}",
            mass=_num(PANDA_MASS),
            diaginertia=_vec(PANDA_INERTIA),
        )
        _geom(body, "palm", type="mesh", mesh="panda_hand", pos=f"0 0 {PANDA_HAND_Z:g}")
    else:
        ET.SubElement(
            body,
            "inertial",
            pos="0 0 -0.08",
            mass=_num(PANDA_MASS),
            diaginertia=_vec(PANDA_INERTIA),
        )
        for i, box in enumerate(gripper.palm):
            _box(body, f"palm{i}", box)
    spec_fingers: list[str] = []
    actuators: list[ET.Element] = []
    travel = gripper.max_width / 2
    for side, label in ((1.0, "left"), (-1.0, "right")):
        movable = gripper.can_close and travel > 0
        parent = body
        if movable:
            parent = ET.SubElement(body, "body", name=f"finger_{label}", pos="0 0 0")
            parent.set("gravcomp", "1")
            joint = f"finger_{label}_slide"
            ET.SubElement(
                parent,
                "joint",
                name=joint,
                type="slide",
                axis=f"0 {side:g} 0",
                range=f"0 {travel:g}",
                limited="true",
                damping="40",
                armature="0.1",
            )
            ET.SubElement(
                parent,
                "inertial",
                pos=f"0 {side * 0.01:g} -0.03",
                mass=_num(FINGER_MASS),
                diaginertia="2.4e-6 2.4e-6 7.5e-7",
            )
            spec_fingers.append(joint)
            act = ET.Element(
                "position",
                name=f"{joint}_servo",
                joint=joint,
                kp=_num(FINGER_KP),
                forcelimited="true",
                forcerange=f"{-grasp_force:g} {grasp_force:g}",
                ctrlrange=f"0 {travel:g}",
                ctrllimited="true",
            )
            actuators.append(act)
        pad = HandBox(
            "pad",
            (0.0, side * gripper.finger_thickness / 2, -gripper.finger_length / 2),
            (gripper.finger_width / 2, gripper.finger_thickness / 2, gripper.finger_length / 2),
        )
        g = _box(parent, f"pad_{label}", pad)
        g.set("friction", PAD_FRICTION)
        g.set("condim", "4")
        g.set("solref", PAD_SOLREF)
        g.set("solimp", PAD_SOLIMP)
        for i, block in enumerate(gripper.fingers):
            _box(parent, f"finger_{label}{i}", block if side > 0 else block.mirrored())
        if panda:
            vis = ET.SubElement(
                parent,
                "geom",
                name=f"finger_{label}_visual",
                type="mesh",
                mesh="panda_finger",
                pos=f"0 0 {PANDA_HAND_Z + PANDA_FINGER_Z:g}",
                contype="0",
                conaffinity="0",
                group="2",
                rgba="0.9 0.9 0.9 1",
            )
            if side < 0:  # the right finger is the left one turned half a turn (panda.urdf)
                vis.set("euler", f"0 0 {math.pi:g}")
    spec = HandSpec(
        gripper,
        fingers=tuple(spec_fingers),
        actuators=tuple(a.get("name", "") for a in actuators),
        finger_travel=travel if spec_fingers else 0.0,
        grasp_force=grasp_force,
    )
    return spec, assets, body, actuators


def _box(parent: ET.Element, name: str, box: HandBox) -> ET.Element:
    pose = box.pose()
    return _geom(
        parent,
        name,
        type="box",
        size=_vec(box.half_extents),
        pos=_vec(pose[:3, 3]),
        quat=_vec(quat_wxyz(pose)),
    )


def _geom(parent: ET.Element, name: str, **attrs: str) -> ET.Element:
    g = ET.SubElement(parent, "geom", {"name": f"hand_{name}", **attrs})
    g.set("contype", str(HAND_GROUP))
    g.set("conaffinity", str(OBJECT_GROUP))
    g.set("rgba", "0.35 0.35 0.4 1")
    return g


def quat_wxyz(pose: np.ndarray) -> np.ndarray:
    """MuJoCo's (w, x, y, z) quaternion of a rotation (the 3x3 block of ``pose``)."""
    import mujoco

    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(pose[:3, :3], dtype=float).reshape(-1))
    return q


def _vec(v: object) -> str:
    return " ".join(_num(float(x)) for x in np.asarray(v, float).ravel())


def _num(x: float) -> str:
    return f"{x:.9g}"
