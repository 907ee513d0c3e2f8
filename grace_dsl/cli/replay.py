"""A traced episode as the project's HTML 3D viewer page: every drawn body's motion replayed.

The world's visible geometry (the object's whole visual pieces and the hand's geoms, meshes and
boxes) becomes the viewer's parts, posed as at the first traced frame; each part then moves
rigidly with its body, frame by frame (``grace_dsl.render.robot.Animation``), with the task's
joint value shown beside the time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.render.html import scene_html
from grace_dsl.render.robot import Animation
from grace_dsl.render.scene import MeshPart, Scene
from grace_dsl.sim.replay import ReplayError

_BOX_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
_BOX_FACES = np.array(
    [
        [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
        [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
    ]
)  # fmt: skip


def replay_html(world: Any, joint: str, title: str, pose: np.ndarray, path: Path) -> Path:
    """Write the viewer page of ``world``'s trace; ``joint`` the concept joint shown, ``pose``
    the object's placement (world <- concept: the viewer's up is its +y)."""
    from grace_dsl.cli.files import atomic_write

    if len(world.trace) < 2:
        raise ReplayError("the world was not traced: replay the episode with fps > 0")
    model = world.model
    times = np.array([t for t, *_ in world.trace])
    first = _body_poses(world.trace[0])
    parts, bodies = [], []
    for g in range(model.ngeom):
        verts_faces = _geom_mesh(model, g)
        if verts_faces is None or not _visible(model, g, world.hand_body):
            continue
        verts, faces = verts_faces
        b = int(model.geom_bodyid[g])
        at = first[b] @ _geom_local(model, g)
        world_verts = verts @ at[:3, :3].T + at[:3, 3]
        rgba = model.geom_rgba[g]
        colour = (float(rgba[0]), float(rgba[1]), float(rgba[2]))
        parts.append(MeshPart(model.body(b).name or "world", world_verts, faces, colour))
        bodies.append(b)
    tracks: dict[int, np.ndarray] = {}
    inverse = {b: np.linalg.inv(first[b]) for b in set(bodies)}
    frames = [_body_poses(f) for f in world.trace]
    for i, b in enumerate(bodies):
        if b != 0:
            tracks[i] = np.stack([f[b] @ inverse[b] for f in frames])
    adr = world.joint_qpos.get(joint)
    values = np.array([f[1][adr] for f in world.trace]) if adr is not None else None
    scene = Scene(title, np.asarray(pose, float), tuple(parts))
    animation = Animation(times - times[0], tracks, joint, values)
    subtitle = f"replay of {times[-1] - times[0]:.1f} s simulated"
    return atomic_write(path, scene_html(scene, subtitle, animation)).path


def _body_poses(frame: tuple[float, np.ndarray, np.ndarray, np.ndarray]) -> list[np.ndarray]:
    import mujoco

    _, _, xpos, xquat = frame
    out = []
    for p, q in zip(xpos, xquat):
        m = np.eye(4)
        r = np.empty(9)
        mujoco.mju_quat2Mat(r, q)
        m[:3, :3], m[:3, 3] = r.reshape(3, 3), p
        out.append(m)
    return out


def _geom_local(model: Any, g: int) -> np.ndarray:
    import mujoco

    m = np.eye(4)
    r = np.empty(9)
    mujoco.mju_quat2Mat(r, model.geom_quat[g])
    m[:3, :3], m[:3, 3] = r.reshape(3, 3), model.geom_pos[g]
    return m


def _geom_mesh(model: Any, g: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices, faces) of a mesh or box geom in its own frame; None for other types."""
    import mujoco

    kind = int(model.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return _BOX_CORNERS * model.geom_size[g], _BOX_FACES
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        m = int(model.geom_dataid[g])
        v0, nv = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
        f0, nf = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
        return model.mesh_vert[v0 : v0 + nv].astype(float), model.mesh_face[f0 : f0 + nf]
    return None


def _visible(model: Any, g: int, hand: int) -> bool:
    """The object's visual pieces (they collide with nothing) and every geom of the hand that
    is not a duplicate collision box of a finger drawn by its mesh."""
    b = int(model.geom_bodyid[g])
    while b > 0 and b != hand:
        b = int(model.body_parentid[b])
    if b == hand:
        name = model.geom(g).name
        return not (name.startswith("hand_finger_") and not name.endswith("_visual"))
    return int(model.geom_contype[g]) == 0 and int(model.geom_conaffinity[g]) == 0
