"""Robot-versus-object and self collision with coal (through Pinocchio's geometry model).

A :class:`CollisionScene` holds the robot's collision geometry (the convex hull of each URDF
collision mesh: exact for the Panda's convex-ish links and far faster for distances than the
triangle soup) and an instance's links as triangle meshes (BVH), posed in the robot's base frame.
Self-collision pairs are all pairs of robot bodies on different joints minus the pairs the
robot's SRDF disables (adjacent links that always touch).

The object's links keep their own meshes (in the link's frame) and are placed by their poses, so
``scene.place(inst)`` moves them to another instance's joint values (an opening door) without
rebuilding anything. Pairs named in ``touching`` (the fingers and the grasped link) may
interpenetrate by up to ``allowance``: a hand holding a handle touches it, nothing else may.
"""

from __future__ import annotations

import weakref
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
    object_links: tuple[str, ...] = ()
    to_base: FloatArray = field(default_factory=lambda: np.eye(4), repr=False)
    touching: tuple[int, ...] = ()  # collision pair indices allowed to penetrate by `allowance`
    allowance: float = 0.0
    _data: Any = field(default=None, repr=False)

    def _geometry_data(self) -> Any:
        if self._data is None:
            self._data = self.geometry.createData()
            for request in self._data.collisionRequests:
                request.security_margin = self.margin
            for k in self.touching:
                self._data.deactivateCollisionPair(k)  # checked on their own, with the allowance
                request = self._data.collisionRequests[k]
                request.enable_contact = True
                request.num_max_contacts = 64
        return self._data

    def place(self, inst: Any) -> None:
        """Pose the object's links as in ``inst`` (the same concept at other joint values)."""
        for k, link in zip(self.object_geoms, self.object_links):
            self.geometry.geometryObjects[k].placement = pin.SE3(
                self.to_base @ inst.link_pose(link)
            )

    def collides(self, q: Any) -> bool:
        """True when any pair is in contact (closer than ``margin``) at configuration ``q``, a
        ``touching`` pair only when it penetrates deeper than ``allowance``."""
        q = self.robot.check_q(q)
        data = self._geometry_data()
        if pin.computeCollisions(self.robot.model, self.robot.data(), self.geometry, data, q, True):
            return True
        return any(self._depth(k) > self.allowance for k in self.touching)

    def _depth(self, k: int) -> float:
        """How deep the pair ``k`` interpenetrates (0 when apart), placements already updated."""
        data = self._data
        if not pin.computeCollision(self.geometry, data, k):
            return 0.0
        result = data.collisionResults[k]
        depths = [abs(result.getContact(i).penetration_depth) for i in range(result.numContacts())]
        return max(depths, default=0.0)

    def contacts(self, q: Any) -> list[Contact]:
        """Every pair in contact at ``q``, with its signed distance (a ``touching`` pair only
        when deeper than the allowance; its distance is then minus the depth)."""
        q = self.robot.check_q(q)
        data = self._geometry_data()
        pin.computeCollisions(self.robot.model, self.robot.data(), self.geometry, data, q, False)
        found = []
        touching = set(self.touching)
        for k, result in enumerate(data.collisionResults):
            pair = self.geometry.collisionPairs[k]
            if k in touching:
                depth = self._depth(k)
                if depth > self.allowance:
                    found.append(Contact(self._name(pair.first), self._name(pair.second), -depth))
            elif result.isCollision():
                distance = pin.computeDistance(self.geometry, data, k).min_distance
                found.append(Contact(self._name(pair.first), self._name(pair.second), distance))
        return found

    def distance(self, q: Any) -> float:
        """The smallest distance between any pair at ``q`` (negative when they penetrate), the
        ``touching`` pairs left out (they may touch)."""
        return min(self._distances(q), default=np.inf)

    def object_distance(self, q: Any) -> float:
        """The smallest distance between the robot and the object at ``q`` (inf without one),
        the ``touching`` pairs left out."""
        objects = set(self.object_geoms)
        pairs = self.geometry.collisionPairs
        found = [
            d
            for k, (d, p) in enumerate(zip(self._distances(q), pairs))
            if p.second in objects and np.isfinite(d)
        ]
        return min(found, default=np.inf)

    def _distances(self, q: Any) -> list[float]:
        q = self.robot.check_q(q)
        data = self._geometry_data()
        pin.computeDistances(self.robot.model, self.robot.data(), self.geometry, data, q)
        touching = set(self.touching)
        return [
            np.inf if k in touching else float(r.min_distance)
            for k, r in enumerate(data.distanceResults)
        ]

    def _name(self, index: int) -> str:
        return str(self.geometry.geometryObjects[index].name)


def collision_scene(
    robot: Robot,
    inst: Any = None,
    *,
    margin: float = 0.0,
    ignore: Sequence[str] = (),
    touching: Sequence[tuple[str, str]] = (),
    allowance: float = 0.005,
    srdf: str | Path | None = None,
    base: Any = None,
    obstacles: Sequence[Any] = (),
) -> CollisionScene:
    """The collision scene of ``robot``, its base at world pose ``base`` (default the origin),
    and the instance ``inst``.

    ``obstacles``: other posed instances (the rest of a room) that stand still: every robot
    body, the fingers included, must keep clear of them; ``place`` does not move them.

    ``ignore`` names robot bodies (prefixes of their geometry names, e.g. ``panda_leftfinger``)
    that may touch the object: the fingers at a grasp. ``srdf`` defaults to the one beside the
    robot's URDF (``../srdf/<name>.srdf``) when it exists. ``touching`` names pairs
    ``(robot body prefix, object link)`` that may interpenetrate by up to ``allowance`` metres:
    the fingers and the link they hold.
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
    object_geoms = [geometry.addGeometryObject(g) for _, g in objects]
    links = [link for link, _ in objects]
    allowed = []
    for i in robot_geoms:
        name = geometry.geometryObjects[i].name
        if any(name.startswith(prefix) for prefix in ignore):
            continue
        for j, link in zip(object_geoms, links):
            geometry.addCollisionPair(pin.CollisionPair(i, j))
            if any(name.startswith(body) and link == held for body, held in touching):
                allowed.append(geometry.findCollisionPair(pin.CollisionPair(i, j)))
    for obstacle in obstacles:
        for _, g in _object_geometry(obstacle, to_base):
            k = geometry.addGeometryObject(g)
            for i in robot_geoms:
                geometry.addCollisionPair(pin.CollisionPair(i, k))
    return CollisionScene(
        robot,
        geometry,
        tuple(robot_geoms),
        tuple(object_geoms),
        margin,
        tuple(links),
        to_base,
        tuple(allowed),
        float(allowance),
    )


def _convex_hull(geometry: Any) -> Any:
    if isinstance(geometry, coal.BVHModelBase):
        geometry.buildConvexRepresentation(False)
        return geometry.convex
    return geometry


def _remove_srdf_pairs(robot: Robot, geometry: pin.GeometryModel, srdf: str | Path | None) -> None:
    path = Path(srdf) if srdf else robot.urdf.parent.parent / "srdf" / f"{robot.urdf.stem}.srdf"
    if path.is_file():
        pin.removeCollisionPairs(robot.model, geometry, str(path), False)


def _object_geometry(inst: Any, to_base: FloatArray) -> list[tuple[str, pin.GeometryObject]]:
    """One BVH mesh per link of ``inst`` that has shapes, in the link's frame, placed at the
    link's pose in the robot's base frame."""
    out = []
    for link, bvh in _link_bvhs(inst):
        placement = pin.SE3(to_base @ inst.link_pose(link))
        out.append((link, pin.GeometryObject(f"object/{link}", 0, placement, bvh)))
    return out


# Each instance's link meshes as BVHs in their links' frames, built once per instance: a plan
# builds a scene per grasp posture and hand (open, closed, letting go), each of the same
# object, and the meshes (boolean unions of the shapes) cost most of a scene. Read-only once
# built, so scenes share them.
_BVHS: weakref.WeakKeyDictionary[Any, list[tuple[str, Any]]] = weakref.WeakKeyDictionary()


def _link_bvhs(inst: Any) -> list[tuple[str, Any]]:
    if inst in _BVHS:
        return _BVHS[inst]
    out = []
    for link in inst.links:  # the copies its counts leave out have no geometry
        mesh = inst.link_mesh(link)
        if len(mesh.faces) == 0:
            continue
        to_link = np.linalg.inv(inst.link_pose(link))
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(mesh.faces), len(mesh.vertices))
        vertices = np.asarray(mesh.vertices, dtype=float) @ to_link[:3, :3].T + to_link[:3, 3]
        bvh.addVertices(np.ascontiguousarray(vertices))
        bvh.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
        bvh.endModel()
        out.append((link, bvh))
    _BVHS[inst] = out
    return out
