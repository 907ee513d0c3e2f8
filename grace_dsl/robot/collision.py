"""Robot-versus-object and self collision with coal (through Pinocchio's geometry model).

A :class:`CollisionScene` holds the robot's collision geometry (the convex hull of each URDF
collision mesh: exact for the Panda's convex-ish links and far faster for distances than the
triangle soup) and an instance's links as triangle meshes (BVH), posed in the robot's base frame.
Self-collision pairs are all pairs of robot bodies on different joints minus the pairs the
robot's SRDF disables (adjacent links that always touch).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from grace_dsl.robot.model import Robot, rigid_pose

FloatArray = np.ndarray


@dataclass(frozen=True)
class Contact:
    """Two bodies closer than the scene's margin (distance may be negative: penetration)."""

    first: str
    second: str
    distance: float


@dataclass(eq=False)
class CollisionScene:
    """The robot and (optionally) one instance; ``collides(q)`` and ``distance(q)`` query it."""

    robot: Robot
    geometry: pin.GeometryModel
    robot_geoms: tuple[int, ...]
    object_geoms: tuple[int, ...]
    margin: float = 0.0
    _data: Any = field(default=None, repr=False)

    def _geometry_data(self) -> Any:
        if self._data is None:
            self._data = self.geometry.createData()
            for request in self._data.collisionRequests:
                request.security_margin = self.margin
        return self._data

    def collides(self, q: Any) -> bool:
        """True when any pair is in contact (closer than ``margin``) at configuration ``q``."""
        q = self.robot.check_q(q)
        return bool(
            pin.computeCollisions(
                self.robot.model, self.robot.data(), self.geometry, self._geometry_data(), q, True
            )
        )

    def contacts(self, q: Any) -> list[Contact]:
        """Every pair in contact at ``q``, with its signed distance."""
        q = self.robot.check_q(q)
        data = self._geometry_data()
        pin.computeCollisions(self.robot.model, self.robot.data(), self.geometry, data, q, False)
        found = []
        for k, result in enumerate(data.collisionResults):
            if result.isCollision():
                pair = self.geometry.collisionPairs[k]
                distance = pin.computeDistance(self.geometry, data, k).min_distance
                found.append(Contact(self._name(pair.first), self._name(pair.second), distance))
        return found

    def distance(self, q: Any) -> float:
        """The smallest distance between any pair at ``q`` (negative when they penetrate)."""
        return min(self._distances(q), default=np.inf)

    def object_distance(self, q: Any) -> float:
        """The smallest distance between the robot and the object at ``q`` (inf without one)."""
        objects = set(self.object_geoms)
        pairs = self.geometry.collisionPairs
        found = [d for d, p in zip(self._distances(q), pairs) if p.second in objects]
        return min(found, default=np.inf)

    def _distances(self, q: Any) -> list[float]:
        q = self.robot.check_q(q)
        data = self._geometry_data()
        pin.computeDistances(self.robot.model, self.robot.data(), self.geometry, data, q)
        return [float(r.min_distance) for r in data.distanceResults]

    def _name(self, index: int) -> str:
        return str(self.geometry.geometryObjects[index].name)


def collision_scene(
    robot: Robot,
    inst: Any = None,
    *,
    margin: float = 0.0,
    ignore: Sequence[str] = (),
    srdf: str | Path | None = None,
    base: Any = None,
) -> CollisionScene:
    """The collision scene of ``robot``, its base at world pose ``base`` (default the origin),
    and the instance ``inst``.

    ``ignore`` names robot bodies (prefixes of their geometry names, e.g. ``panda_leftfinger``)
    that may touch the object: the fingers at a grasp. ``srdf`` defaults to the one beside the
    robot's URDF (``../srdf/<name>.srdf``) when it exists.
    """
    geometry = pin.GeometryModel()
    robot_geoms = []
    for obj in robot.collision.geometryObjects:
        hull = pin.GeometryObject(obj)
        hull.geometry = _convex_hull(obj.geometry)
        robot_geoms.append(geometry.addGeometryObject(hull))
    geometry.addAllCollisionPairs()
    _remove_srdf_pairs(robot, geometry, srdf)
    to_base = np.eye(4) if base is None else np.linalg.inv(rigid_pose(base, "the robot base pose"))
    objects = _object_geometry(inst, to_base) if inst is not None else []
    object_geoms = [geometry.addGeometryObject(g) for g in objects]
    for i in robot_geoms:
        name = geometry.geometryObjects[i].name
        if any(name.startswith(prefix) for prefix in ignore):
            continue
        for j in object_geoms:
            geometry.addCollisionPair(pin.CollisionPair(i, j))
    return CollisionScene(robot, geometry, tuple(robot_geoms), tuple(object_geoms), margin)


def _convex_hull(geometry: Any) -> Any:
    if isinstance(geometry, coal.BVHModelBase):
        geometry.buildConvexRepresentation(False)
        return geometry.convex
    return geometry


def _remove_srdf_pairs(robot: Robot, geometry: pin.GeometryModel, srdf: str | Path | None) -> None:
    path = Path(srdf) if srdf else robot.urdf.parent.parent / "srdf" / f"{robot.urdf.stem}.srdf"
    if path.is_file():
        pin.removeCollisionPairs(robot.model, geometry, str(path), False)


def _object_geometry(inst: Any, to_base: FloatArray) -> list[pin.GeometryObject]:
    """One static BVH mesh per link of ``inst`` that has shapes, in the robot's base frame."""
    out = []
    for link in inst.links:  # the copies its counts leave out have no geometry
        mesh = inst.link_mesh(link)
        if len(mesh.faces) == 0:
            continue
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(mesh.faces), len(mesh.vertices))
        vertices = np.asarray(mesh.vertices, dtype=float) @ to_base[:3, :3].T + to_base[:3, 3]
        bvh.addVertices(np.ascontiguousarray(vertices))
        bvh.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
        bvh.endModel()
        out.append(pin.GeometryObject(f"object/{link}", 0, pin.SE3.Identity(), bvh))
    return out
