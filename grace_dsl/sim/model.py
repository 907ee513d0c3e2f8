"""An instance as a MuJoCo model, standing upright in a z-up world.

Concepts are written y-up (their +y is up, +z their front); MuJoCo's gravity is along -z. So
the simulator places an instance with ``zup_pose``: the concept frame turned +90 degrees about x
(concept +y -> world +z, concept +z (front) -> world -y, x stays x), then turned by ``yaw`` about
world z, and moved so that its lowest point at q = 0 rests on the floor (z = 0) at ``xy``. A
door's hinge, vertical in the concept, is then vertical in the world, and gravity no longer
swings it.

``instance_model`` builds the exported MJCF of a posed instance (``grace_dsl.export.mjcf``) and
its initial state (the instance's joint values, the keyframe ``instance``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from grace_dsl.export import ExportOptions, export_mjcf

if TYPE_CHECKING:
    import mujoco

    from grace_dsl.runtime.instance import Instance

#: world <- concept frame: +90 degrees about x (y-up to z-up).
Y_UP_TO_Z_UP = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)


def zup_pose(
    inst: Instance | None = None, xy: Sequence[float] = (0.0, 0.0), yaw: float = 0.0
) -> np.ndarray:
    """The world pose (4x4) that stands a y-up concept upright in a z-up world: concept +y ->
    world +z, turned by ``yaw`` (rad) about world z, its concept origin above ``xy``; with
    ``inst``, lifted so that its lowest point at q = 0 touches z = 0 (the floor)."""
    c, s = math.cos(yaw), math.sin(yaw)
    turn = np.eye(4)
    turn[:2, :2] = [[c, -s], [s, c]]
    pose = turn @ Y_UP_TO_Z_UP
    pose[:2, 3] = xy
    if inst is not None:
        pose[2, 3] = -lowest_y(inst)
    return pose


def lowest_y(inst: Instance) -> float:
    """The instance's lowest point along its concept's +y with its joints closed (concept
    frame): how far below its origin its base reaches."""
    from grace_dsl.runtime.shapes import instance_meshes

    closed = inst.with_joints({j: 0.0 for j in _closable(inst)}).with_pose(np.eye(4))
    meshes = instance_meshes(closed, resolution=16)
    if not meshes:
        return 0.0
    return float(min(np.asarray(m.vertices)[:, 1].min() for m in meshes))


def _closable(inst: Instance) -> list[str]:
    """The joints whose range holds 0 (the closed state)."""
    return [n for n, (lo, hi) in inst.joint_limits().items() if lo <= 0.0 <= hi]


def upright(inst: Instance, xy: Sequence[float] = (0.0, 0.0), yaw: float = 0.0) -> Instance:
    """``inst`` standing on the floor of a z-up world (``zup_pose``)."""
    return inst.with_pose(zup_pose(inst, xy, yaw))


def instance_model(
    inst: Instance, options: ExportOptions | None = None
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The compiled MuJoCo model of ``inst`` (at its own pose; use ``upright`` first for a
    z-up world) and data at its joint values."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(export_mjcf(inst, options=options))
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    return model, data


@dataclass(frozen=True)
class Settle:
    """How a model behaved left alone under gravity (``settle``): the deepest contact between
    two of its own bodies over the run (m, positive = overlap) and where, the deepest at the
    start (a state drawn overlapping) and at the end (after impacts settle); each joint's
    largest distance outside its range and its drift from its start (m or rad)."""

    penetration: float
    pair: tuple[str, str]  # the bodies of the deepest contact ("", "") when none
    outside: dict[str, float]
    drift: dict[str, float]
    initial: float = 0.0
    final: float = 0.0


def settle(model: mujoco.MjModel, data: mujoco.MjData, seconds: float = 1.0) -> Settle:
    """Step ``model`` from ``data`` for ``seconds`` with no actuation, tracking the deepest
    contact between distinct bodies and every limited joint's excursion from its range."""
    import mujoco

    joints = [j for j in range(model.njnt) if model.jnt_type[j] in (2, 3)]  # slide, hinge
    adr = model.jnt_qposadr[joints]
    start = data.qpos[adr].copy()
    lo, hi = model.jnt_range[joints, 0], model.jnt_range[joints, 1]
    limited = model.jnt_limited[joints].astype(bool)
    outside = np.zeros(len(joints))
    drift = np.zeros(len(joints))
    deepest, pair = 0.0, ("", "")
    mujoco.mj_forward(model, data)
    initial = _deepest(model, data)
    for _ in range(max(1, round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
        q = data.qpos[adr]
        excess = np.where(limited, np.maximum(lo - q, q - hi), 0.0)
        outside = np.maximum(outside, excess)
        drift = np.maximum(drift, np.abs(q - start))
        for c in data.contact[: data.ncon]:
            b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
            if b1 != b2 and -c.dist > deepest:
                deepest = float(-c.dist)
                pair = (_body(model, b1), _body(model, b2))
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or str(j) for j in joints]
    return Settle(
        deepest,
        pair,
        dict(zip(names, np.maximum(outside, 0.0).tolist())),
        dict(zip(names, drift.tolist())),
        initial,
        _deepest(model, data),
    )


def _deepest(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The deepest overlap (m) between two distinct bodies in ``data``'s contacts."""
    depths = [
        -c.dist
        for c in data.contact[: data.ncon]
        if model.geom_bodyid[c.geom1] != model.geom_bodyid[c.geom2]
    ]
    return max([0.0, *depths])


def _body(model: mujoco.MjModel, b: int) -> str:
    import mujoco

    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b)) or str(b)
