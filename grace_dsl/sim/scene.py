"""A physical scene of concept instances: floor, lights, the objects standing z-up, an RGB-D camera.

    scene = sim.Scene.from_instances([inst], camera=sim.Camera.random(rng))
    model, data = scene.compile()              # MuJoCo, the objects at their joint values
    frame = scene.render(model, data)          # rgb (H, W, 3), depth (m), segmentation (body ids)
    cloud = scene.point_cloud(frame)           # camera- and world-frame points, link per point

Each instance is exported (``grace_dsl.export.mjcf``: convex collision pieces, whole visual
meshes) and attached to one ``mujoco.MjSpec``. By default (``up="z"``) an instance is stood
upright on the floor (``sim.model.zup_pose``: concept +y -> world +z), the first at the origin
and the next ones 1.5 m apart along world x; ``up="keep"`` uses each instance's own pose as
its world pose. The i-th instance's names are the exported ones with the prefix ``obj<i>/``
(the first instance's joint ``door.hinge`` is ``obj0/door__hinge``; ``scene.name(0, ...)``).

Extension hook (the hand, the arm): ``scene.spec(extra=[hand_spec, ...])`` returns the
composed ``MjSpec`` with each extra ``MjSpec`` attached to the world (its bodies, assets,
actuators, mocap bodies and contact settings come along; a copy is attached, so one spec can
serve several scenes; pass one already prefixed, or give ``(spec, prefix)`` pairs);
``scene.compile(extra=...)`` compiles it and sets every instance's joints (by name, so extra
joints anywhere in qpos do no harm), and ``scene.mjcf(extra=...)`` is its XML text.

Rendering is headless (``MUJOCO_GL=osmesa`` or ``egl``). Segmentation holds MuJoCo body ids
(-1 for the sky, 0 the world: the floor); ``link_of`` maps a body id to (instance index,
concept link).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from grace_dsl.export import ExportOptions, build_model, write_mjcf
from grace_dsl.export.model import ExportModel
from grace_dsl.runtime.errors import GraceError
from grace_dsl.sim.camera import Camera, back_project, to_world
from grace_dsl.sim.model import zup_pose

if TYPE_CHECKING:
    import mujoco

    from grace_dsl.runtime.instance import Instance

SPACING = 1.5  # m between instances along world x
CLEARANCE = 0.002  # m between an object's lowest point and the floor
TIMESTEP = 0.002  # s
FRAMING = 1.15  # the default distance fits the objects' bounding sphere, with this margin

_BASE = """
<mujoco model="scene">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{timestep}" gravity="0 0 -9.81" integrator="implicitfast" cone="elliptic"/>
  <visual>
    <global offwidth="{width}" offheight="{height}"/>
    <map znear="0.01" zfar="20"/>
    <quality shadowsize="2048"/>
    <headlight ambient="0.35 0.35 0.35" diffuse="0.4 0.4 0.4" specular="0.1 0.1 0.1"/>
  </visual>
  <statistic extent="1" center="0 0 0.5"/>
  <asset>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.82 0.82 0.8" rgb2="0.72 0.72 0.7"
      width="256" height="256"/>
    <material name="floor" texture="grid" texrepeat="8 8" reflectance="0"/>
  </asset>
  <worldbody>
    <light name="key" pos="2 -2 4" dir="-0.45 0.45 -0.77" directional="true"
      diffuse="0.6 0.6 0.6" castshadow="false"/>
    <light name="fill" pos="-2 2 3" dir="0.5 -0.5 -0.7" directional="true"
      diffuse="0.25 0.25 0.25" castshadow="false"/>
    <geom name="floor" type="plane" size="0 0 0.05" material="floor" group="0"/>
  </worldbody>
</mujoco>
"""


class SceneError(GraceError):
    """A scene that cannot be built: no instances, an unknown ``up``, mismatched poses."""


@dataclass(frozen=True)
class Frame:
    """One camera image: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) metres along the viewing
    axis (0: nothing hit), ``segmentation`` (H, W) MuJoCo body ids (-1: nothing), and the
    camera that took it (target and distance filled in)."""

    rgb: np.ndarray
    depth: np.ndarray
    segmentation: np.ndarray
    camera: Camera


@dataclass(frozen=True)
class PointCloud:
    """The pixels that hit something: camera- and world-frame points (N, 3) and their body ids."""

    camera_points: np.ndarray
    world_points: np.ndarray
    bodies: np.ndarray


@dataclass(frozen=True)
class Scene:
    """Posed instances (world poses), their exported models and the camera."""

    instances: tuple[Instance, ...]
    models: tuple[ExportModel, ...]
    camera: Camera
    prefixes: tuple[str, ...] = field(default=())
    texts: tuple[str, ...] = field(default=(), repr=False)  # each model's MJCF, written once

    @classmethod
    def from_instances(
        cls,
        instances: Sequence[Instance],
        camera: Camera | None = None,
        up: Literal["z", "keep"] = "z",
        yaw: Sequence[float] | None = None,
        options: ExportOptions | None = None,
    ) -> Scene:
        """A scene of ``instances``: stood upright (``up="z"``, turned by ``yaw`` radians about
        world z) or at their own poses (``up="keep"``), seen by ``camera`` (default: azimuth
        45, elevation 45 degrees), aimed at the objects' centre unless it has a target."""
        if not instances:
            raise SceneError("a scene needs at least one instance")
        if up not in ("z", "keep"):
            raise SceneError(f"up must be 'z' (stand upright) or 'keep' (own poses), got {up!r}")
        turns = list(yaw) if yaw is not None else [0.0] * len(instances)
        if len(turns) != len(instances):
            raise SceneError(f"{len(turns)} yaw angles for {len(instances)} instances")
        placed = []
        for i, inst in enumerate(instances):
            if up == "z":
                pose = zup_pose(inst, (i * SPACING, 0.0), turns[i])
                pose[2, 3] += CLEARANCE
                inst = inst.with_pose(pose)
            placed.append(inst)
        models = tuple(build_model(inst, options) for inst in placed)
        centre, radius = _bounds(placed)
        cam = camera or Camera()
        cam = cam.aimed(centre, FRAMING * radius / np.sin(np.radians(cam.fovy) / 2))
        prefixes = tuple(f"obj{i}/" for i in range(len(placed)))
        texts = tuple(write_mjcf(m) for m in models)
        return cls(tuple(placed), models, cam, prefixes, texts)

    # -- the model -----------------------------------------------------------------------------
    def spec(
        self, extra: Sequence[mujoco.MjSpec | tuple[mujoco.MjSpec, str]] = ()
    ) -> mujoco.MjSpec:
        """The scene as one ``MjSpec``: floor, lights, camera ``view``, the instances and the
        ``extra`` specs (each attached to the world, optionally with a name prefix)."""
        import mujoco

        cam = self.camera
        root = mujoco.MjSpec.from_string(
            _BASE.format(timestep=TIMESTEP, width=max(cam.width, 640), height=max(cam.height, 480))
        )
        pose = cam.pose()
        root.worldbody.add_camera(
            name="view",
            pos=pose[:3, 3],
            xyaxes=np.concatenate([pose[:3, 0], pose[:3, 1]]),
            fovy=cam.fovy,
        )
        texts = self.texts or tuple(write_mjcf(m) for m in self.models)
        for text, prefix in zip(texts, self.prefixes):
            child = mujoco.MjSpec.from_string(text)
            for key in list(child.keys):
                child.delete(key)  # joint values are set by name after compiling
            root.attach(child, prefix=prefix, frame=root.worldbody.add_frame())
        for item in extra:
            spec, prefix = item if isinstance(item, tuple) else (item, "")
            root.attach(spec.copy(), prefix=prefix, frame=root.worldbody.add_frame())
        return root

    def mjcf(self, extra: Sequence[mujoco.MjSpec | tuple[mujoco.MjSpec, str]] = ()) -> str:
        """The composed scene's MJCF text (see ``spec``)."""
        spec = self.spec(extra)
        spec.compile()
        return str(spec.to_xml())

    def compile(
        self, extra: Sequence[mujoco.MjSpec | tuple[mujoco.MjSpec, str]] = ()
    ) -> tuple[mujoco.MjModel, mujoco.MjData]:
        """The compiled model and its data with every instance's joints at their values."""
        import mujoco

        model = self.spec(extra).compile()
        data = mujoco.MjData(model)
        for exported, prefix in zip(self.models, self.prefixes):
            for j in exported.joints:
                if j.kind != "fixed":
                    adr = model.jnt_qposadr[model.joint(prefix + j.name).id]
                    data.qpos[adr] = j.value
        mujoco.mj_forward(model, data)
        return model, data

    def name(self, index: int, exported: str) -> str:
        """The scene's name of instance ``index``'s body, joint or geom named ``exported`` in
        its own MJCF (``grace_dsl.export``)."""
        return self.prefixes[index] + exported

    def link_of(self, model: mujoco.MjModel, body: int) -> tuple[int, str] | None:
        """(instance index, concept link) of MuJoCo body ``body``; None for the world, the
        floor and extra bodies."""
        name = model.body(int(body)).name if 0 < body < model.nbody else ""
        for i, (exported, prefix) in enumerate(zip(self.models, self.prefixes)):
            for link in exported.links:
                if name == prefix + link.name:
                    return i, link.source
        return None

    # -- the camera ----------------------------------------------------------------------------
    def render(self, model: mujoco.MjModel, data: mujoco.MjData) -> Frame:
        """RGB, depth (metres) and body segmentation from camera ``view`` (headless)."""
        import mujoco

        cam = self.camera
        with mujoco.Renderer(model, cam.height, cam.width) as renderer:
            renderer.update_scene(data, camera="view")
            rgb = renderer.render().copy()
            renderer.enable_depth_rendering()
            renderer.update_scene(data, camera="view")
            depth = renderer.render().copy()
            renderer.disable_depth_rendering()
            renderer.enable_segmentation_rendering()
            renderer.update_scene(data, camera="view")
            seg = renderer.render().copy()
        ids, types = seg[..., 0], seg[..., 1]
        geom = types == int(mujoco.mjtObj.mjOBJ_GEOM)
        bodies = np.full(ids.shape, -1, dtype=np.int32)
        bodies[geom] = model.geom_bodyid[ids[geom]]
        far = model.vis.map.zfar * model.stat.extent
        depth = np.where((depth < 0.999 * far) & (bodies >= 0), depth, 0.0).astype(np.float64)
        return Frame(rgb, depth, bodies, cam)

    def point_cloud(self, frame: Frame) -> PointCloud:
        """The depth image back-projected: camera- and world-frame points of every hit pixel."""
        points, hit = back_project(frame.depth, frame.camera)
        cam_pts = points[hit]
        return PointCloud(cam_pts, to_world(cam_pts, frame.camera), frame.segmentation[hit])


def _bounds(instances: Sequence[Instance]) -> tuple[np.ndarray, float]:
    """The centre and half-diagonal of the instances' world bounding box."""
    from grace_dsl.runtime.shapes import instance_meshes

    points = np.vstack(
        [np.asarray(m.vertices) for inst in instances for m in instance_meshes(inst, resolution=16)]
    )
    lo, hi = points.min(axis=0), points.max(axis=0)
    return (lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2)
