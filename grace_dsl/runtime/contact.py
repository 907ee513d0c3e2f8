"""Where the hand is for a contact, and whether its boxes stay out of the part.

A grasp pose says where the contact is: for a pinch or a hook the hand's own frame, for a push the
touched point with +z into the material. A hand may push with its fingertips (its frame is the
grasp's), with the side of a closed finger (a face of the pads pressed on the point, the hand's
approach as close to its home approach as the face allows), with its palm (the palm's front face
on the point) or, for a hand that cannot turn a face onto the part, with the closed fingers'
edge or corner nearest it, the hand at its home orientation (``edge``). ``hand_poses`` turns
grasp poses into hand poses for each; ``HandSweep`` samples the hand's boxes as they come in
(backed off along the contact's -z, then fingers closing) and hold; ``Scene`` evaluates the
part's signed distance at several joint states in one pass per shape, so a whole follow path
costs about as much as one query.

Sampling the hand's faces misses a part thinner than the sample spacing that slices into a box
between two samples (a 6 mm wall plate across a palm sampled every 10 mm). So the check also runs
the other way: points on the part's surface near the hand (``Scene.surface``, sampled once per
instance and shape, cheap) are tested for lying inside the hand's swept boxes, analytically; a
point inside is then followed along the part's inward normal to measure how deep the part reaches
into the box.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.geometry.props import bounds, volume
from grace_dsl.geometry.sample import sample_surface, surface_area
from grace_dsl.geometry.sdf import FORMULAS, NumpyOps
from grace_dsl.runtime.gripper import FingerBox, Gripper, box_surface_grid

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

# Sample spacing on the boxes' faces. A part's solid features are at least 10 mm across (bars of
# radius 5 mm and more, boards of 10 mm and more), so a feature entering a face crosses a grid
# line of these grids; the palm, large and far from the contact, gets a coarser one.
PAD_SPACING = 0.005  # m between sample points on pads and finger blocks
PALM_SPACING = 0.010  # m between sample points on the palm
CLEAR = 0.002  # m of penetration that counts as touching (the rubber pads give that much)
# The reverse check samples the surface of thin primitives only: a part thicker than the face
# grids' spacing cannot pass between two face samples, so the forward check sees it. A
# primitive's thickness is taken as 2 volume / area (a plate's thickness, a rod's radius, a
# tube's wall). About one sample per SURFACE_SPACING square, SURFACE_MIN to SURFACE_MAX each.
THIN = 0.012  # m
SURFACE_SPACING = 0.005  # m
SURFACE_MIN, SURFACE_MAX = 100, 1500
SURFACE_ON = 1e-4  # m: a sample this close to the scene's zero level is on its outer surface
PROBES = 4  # points along the inward normal at which a sample inside a box measures the depth

# Faces of the closed fingers a side push may use: outer normal (hand frame) and which axis it is.
SIDE_FACES = ((0.0, -1.0, 0.0), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (1.0, 0.0, 0.0))


def hand_poses(
    gripper: Gripper, contact: str, grasps: np.ndarray, home: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Hand poses (m, 4, 4) for grasp poses (n, 4, 4) touched by ``contact``, and for each the
    index of its grasp (a side push tries every side face, so m = 4 n). A pinch or a hook takes
    the grasp's orientation; a push only fixes the direction it pushes in, and the hand spins
    about it to the orientation nearest ``home``; an edge push keeps ``home``."""
    n = len(grasps)
    if contact in ("pads", "fingers"):
        return grasps, np.arange(n)
    normals = grasps[:, :3, 2]
    if contact == "edge":  # the hand as it is at home, touching with the fingers' support point
        rot = np.broadcast_to(home, (n, 3, 3))
        return _placed_each(rot, grasps[:, :3, 3], edge_points(gripper, normals @ home)), np.arange(
            n
        )
    if contact in ("tip", "palm"):  # a push does not care how the hand spins about it
        point = palm_point(gripper) if contact == "palm" else np.zeros(3)
        y = _orthogonal(home[:, 1], normals, grasps[:, :3, 1])
        rot = np.stack([np.cross(y, normals), y, normals], axis=-1)
        return _placed(rot, grasps[:, :3, 3], point), np.arange(n)
    z = _orthogonal(home[:, 2], normals, grasps[:, :3, 0])
    poses, index = [], []
    for face in SIDE_FACES:
        axis = int(np.flatnonzero(face)[0])
        sign = float(sum(face))
        out = sign * normals  # the face's outer normal pushes into the material
        if axis == 1:
            rot = np.stack([np.cross(out, z), out, z], axis=-1)
        else:
            rot = np.stack([out, np.cross(z, out), z], axis=-1)
        poses.append(_placed(rot, grasps[:, :3, 3], side_point(gripper, face)))
        index.append(np.arange(n))
    return np.concatenate(poses), np.concatenate(index)


def edge_points(gripper: Gripper, normals: np.ndarray) -> np.ndarray:
    """The point of the closed fingers (one block: x within half the pad's width, y within the
    pad's thickness, z from -finger_length to 0) farthest along each hand-frame direction
    (n, 3): a corner, the middle of an edge or of a face. Put on the contact, the whole block
    stays on the near side of the part's tangent plane there."""
    half = np.array([gripper.finger_width / 2, gripper.finger_thickness, gripper.finger_length / 2])
    sign = np.where(np.abs(normals) < 1e-6, 0.0, np.sign(normals))
    return sign * half + np.array([0.0, 0.0, -gripper.finger_length / 2])


def side_point(gripper: Gripper, face: tuple[float, float, float]) -> np.ndarray:
    """The middle of a closed finger pad's outer face ``face`` (hand frame)."""
    half = (gripper.finger_width / 2, gripper.finger_thickness, 0.0)
    return np.array([face[0] * half[0], face[1] * half[1], -gripper.finger_length / 2])


def palm_point(gripper: Gripper) -> np.ndarray:
    """The middle of the palm's front face: the palm box reaching furthest along +z."""
    best = max(gripper.palm, key=lambda b: _reach(b.pose(), b.half_extents))
    x, y, _ = best.center
    return np.array([x, y, _reach(best.pose(), best.half_extents)])


def _reach(pose: np.ndarray, half: tuple[float, float, float]) -> float:
    return float(pose[2, 3] + np.abs(pose[2, :3]) @ np.asarray(half))


def _orthogonal(want: np.ndarray, normals: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """``want`` made orthogonal to each normal (unit); ``fallback`` where it is along one."""
    v = want[None, :] - (normals @ want)[:, None] * normals
    norm = np.linalg.norm(v, axis=1)
    bad = norm < 1e-6
    v[bad] = fallback[bad] - np.sum(fallback[bad] * normals[bad], axis=1)[:, None] * normals[bad]
    return v / np.linalg.norm(v, axis=1)[:, None]


def _placed_each(rot: np.ndarray, points: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Poses with rotations ``rot`` that put each hand point ``local[i]`` on ``points[i]``."""
    out = np.zeros((len(rot), 4, 4))
    out[:, :3, :3] = rot
    out[:, :3, 3] = points - np.einsum("nij,nj->ni", rot, local)
    out[:, 3, 3] = 1.0
    return out


def _placed(rot: np.ndarray, points: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Poses with rotations ``rot`` that put hand point ``local`` on ``points``."""
    out = np.zeros((len(rot), 4, 4))
    out[:, :3, :3] = rot
    out[:, :3, 3] = points - rot @ local
    out[:, 3, 3] = 1.0
    return out


def rotation_from(home: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """The angle of the smallest rotation from ``home`` to each rotation (..., 3, 3), the hand
    turned half a turn about its approach counting as the same hand (it is symmetric)."""
    a = np.einsum("ji,...jk->...ik", home, rotations)
    trace = a[..., 0, 0] + a[..., 1, 1] + a[..., 2, 2]
    flipped = -a[..., 0, 0] - a[..., 1, 1] + a[..., 2, 2]
    return np.arccos(np.clip((np.maximum(trace, flipped) - 1.0) / 2.0, -1.0, 1.0))


# ---- sampled hand geometry ----------------------------------------------------------------------


CELL = 0.03  # m: points are grouped in cells this size, each tested first by its centre


@dataclass(frozen=True)
class Cloud:
    """Sample points of some boxes (hand frame), grouped in clusters so that a whole cluster
    whose centre lies far enough outside the part is cleared by one distance query: a signed
    distance changes by at most the distance moved (it is 1-Lipschitz)."""

    points: np.ndarray  # (N, 3), cluster by cluster
    parts: tuple[str, ...]  # the box each point belongs to
    owner: np.ndarray  # (N,) the cluster of each point
    centres: np.ndarray  # (M, 3)
    radii: np.ndarray  # (M,) the farthest point of each cluster from its centre

    @staticmethod
    def of(points: np.ndarray, parts: tuple[str, ...]) -> Cloud:
        if not len(points):
            return Cloud(points, (), np.zeros(0, int), np.zeros((0, 3)), np.zeros(0))
        cells = np.floor(points / CELL).astype(np.int64)
        _, owner = np.unique(cells, axis=0, return_inverse=True)
        owner = owner.reshape(-1)
        order = np.argsort(owner, kind="stable")
        points, owner = points[order], owner[order]
        count = int(owner.max()) + 1
        sizes = np.bincount(owner, minlength=count)[:, None]
        centres = np.zeros((count, 3))
        np.add.at(centres, owner, points)
        centres /= sizes
        radii = np.zeros(count)
        np.maximum.at(radii, owner, np.linalg.norm(points - centres[owner], axis=1))
        return Cloud(points, tuple(parts[i] for i in order), owner, centres, radii)


@dataclass(frozen=True)
class Boxes:
    """The volumes some boxes sweep (hand frame), for analytic containment tests: poses (K, 4,
    4) with the box frame's rotation and centre, half extents (K, 3), the box each one is."""

    poses: np.ndarray
    halves: np.ndarray
    parts: tuple[str, ...]

    @staticmethod
    def of(items: list[tuple[np.ndarray, np.ndarray, str]]) -> Boxes:
        if not items:
            return Boxes(np.zeros((0, 4, 4)), np.zeros((0, 3)), ())
        return Boxes(
            np.stack([i[0] for i in items]),
            np.stack([i[1] for i in items]),
            tuple(i[2] for i in items),
        )

    def reach(self) -> tuple[np.ndarray, float]:
        """A sphere (hand frame) holding every box: centre and radius."""
        if not len(self.parts):
            return np.zeros(3), 0.0
        centres = self.poses[:, :3, 3]
        lo = (centres - np.linalg.norm(self.halves, axis=1)[:, None]).min(axis=0)
        hi = (centres + np.linalg.norm(self.halves, axis=1)[:, None]).max(axis=0)
        mid = (lo + hi) / 2
        radius = np.linalg.norm(centres - mid, axis=1) + np.linalg.norm(self.halves, axis=1)
        return mid, float(radius.max())


@dataclass(frozen=True)
class HandSweep:
    """The hand's boxes, sampled on their surfaces, in the phases of one grasp (hand frame):
    ``approach`` the hand coming in along the contact's +z over the approach distance with its
    fingers open, ``closing`` the fingers closing to the grasp's width, and ``hold`` the boxes at
    the grasp (what a follow path carries); the ``*_boxes`` are the same volumes as boxes, for
    the reverse check (the part's surface inside them)."""

    approach: Cloud
    closing: Cloud
    hold: Cloud
    approach_boxes: Boxes
    closing_boxes: Boxes
    hold_boxes: Boxes


def sweep(gripper: Gripper, direction: np.ndarray, open_width: float, hold: float) -> HandSweep:
    """Sample the hand for one contact: see :class:`HandSweep`. ``direction`` is the unit hand
    frame direction the hand moves in on its approach (the contact's +z). Cached: a hand meets
    few distinct directions (its own axes) and widths."""
    key = tuple(float(x) for x in np.round(np.asarray(direction, float), 9))
    return _sweep(gripper, (key[0], key[1], key[2]), round(open_width, 9), round(hold, 9))


@lru_cache(maxsize=256)
def _sweep(
    gripper: Gripper, direction: tuple[float, float, float], open_width: float, hold: float
) -> HandSweep:
    back = -gripper.approach_distance * np.asarray(direction, float)
    approach = Cloud.of(*_points(gripper.hand_boxes(open_width), back))
    approach_boxes = Boxes.of(
        [v for b in gripper.hand_boxes(open_width) for v in swept_volumes(b, back)]
    )
    closing = Cloud.of(np.zeros((0, 3)), ())
    closing_items: list[tuple[np.ndarray, np.ndarray, str]] = []
    if open_width > hold:
        pts, parts = [], []
        for b in gripper.hand_boxes(hold):
            if b.part == "palm":
                continue
            side = 1.0 if b.pose[1, 3] >= 0 else -1.0  # each finger opens along its own side
            offset = np.array([0.0, side * (open_width - hold) / 2, 0.0])
            p, _ = _points((b,), offset)
            pts.append(p)
            parts += [_label(b)] * len(p)
            closing_items += swept_volumes(b, offset)
        closing = Cloud.of(np.concatenate(pts), tuple(parts))
    held = gripper.hand_boxes(hold)
    return HandSweep(
        approach,
        closing,
        Cloud.of(*_points(held, np.zeros(3))),
        approach_boxes,
        Boxes.of(closing_items),
        Boxes.of([v for b in held for v in swept_volumes(b, np.zeros(3))]),
    )


def _label(box: FingerBox) -> str:
    return box.part if box.part in ("pad", "palm") else f"finger block {box.name}".strip()


def _points(boxes: tuple[FingerBox, ...], back: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]]:
    """Surface points of each box swept from ``back`` (offset, hand frame) to where it is."""
    pts: list[np.ndarray] = []
    parts: list[str] = []
    for b in boxes:
        p = swept_box(b, back, PALM_SPACING if b.part == "palm" else PAD_SPACING)
        pts.append(p)
        parts += [_label(b)] * len(p)
    return np.concatenate(pts), tuple(parts)


def swept_box(box: FingerBox, back: np.ndarray, spacing: float) -> np.ndarray:
    """Surface points of the volume a box sweeps moving from ``pose + back`` to ``pose``: a
    longer box when ``back`` lies along one of its axes, else copies of it a box apart."""
    length = float(np.linalg.norm(back))
    if length < 1e-12:
        return box_surface_grid(box, spacing)
    local = box.pose[:3, :3].T @ back
    axis = int(np.argmax(np.abs(local)))
    if np.all(np.delete(np.abs(local), axis) < 1e-9):
        half = list(box.half_extents)
        half[axis] += length / 2
        pose = box.pose.copy()
        pose[:3, 3] += back / 2
        return box_surface_grid(FingerBox(pose, (half[0], half[1], half[2])), spacing)
    step = 2 * min(box.half_extents)
    count = max(2, math.ceil(length / step) + 1)
    grid = box_surface_grid(box, spacing)
    return np.concatenate([grid + t * back for t in np.linspace(0.0, 1.0, count)])


def swept_volumes(box: FingerBox, back: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """The volume a box sweeps moving from ``pose + back`` to ``pose``, as boxes (pose, half
    extents, label): one longer box when ``back`` lies along one of its axes, else copies of it
    at most half a box apart (their union covers the sweep but for slivers at the corners)."""
    half = np.asarray(box.half_extents, dtype=float)
    length = float(np.linalg.norm(back))
    label = _label(box)
    if length < 1e-12:
        return [(box.pose, half, label)]
    local = box.pose[:3, :3].T @ back
    axis = int(np.argmax(np.abs(local)))
    if np.all(np.delete(np.abs(local), axis) < 1e-9):
        grown = half.copy()
        grown[axis] += length / 2
        pose = box.pose.copy()
        pose[:3, 3] += back / 2
        return [(pose, grown, label)]
    count = max(2, math.ceil(length / min(half)) + 1)
    out = []
    for t in np.linspace(0.0, 1.0, count):
        pose = box.pose.copy()
        pose[:3, 3] += t * back
        out.append((pose, half, label))
    return out


# ---- the part at several joint states -----------------------------------------------------------


_SCENES: dict[int, tuple[Instance, Scene]] = {}  # a few recent instances' scenes
SCENE_CACHE = 8


class Scene:
    """The signed distance of an instance's shapes, at its own joints or along joint paths."""

    @staticmethod
    def of(inst: Instance) -> Scene:
        """The scene of ``inst``, shared by the rank calls on the same instance (an instance
        never changes; its shapes' arguments are then checked once, not once per call)."""
        hit = _SCENES.get(id(inst))
        if hit is not None and hit[0] is inst:
            return hit[1]
        scene = Scene(inst)
        if len(_SCENES) >= SCENE_CACHE:
            _SCENES.pop(next(iter(_SCENES)))
        _SCENES[id(inst)] = (inst, scene)
        return scene

    def __init__(self, inst: Instance):
        from grace_dsl.runtime.kinematics import Kinematics
        from grace_dsl.runtime.shapes import ShapeTree

        self.inst = inst
        self.tree = ShapeTree(inst)
        self.names = self.tree.outermost()
        self.kin = Kinematics.of(inst)
        links = {self.tree.shapes[n]["link"] for n in self.names}
        self.rest = {link: np.linalg.inv(self.tree.link_pose(link)) for link in links}
        self.placements = {n: self.tree.placement(n) for n in self.names}
        self._own: dict[str, np.ndarray] = {}  # world -> rest, per link, at the instance's q
        self._inv: dict[str, np.ndarray] = {}  # each shape's placement inverted
        self._leaves: list[Leaf] | None = None  # the thin primitives, sampled lazily
        self._moved_at: dict[bytes, set[str]] = {}

    def sdf(
        self, points: list[np.ndarray], qs: np.ndarray | None = None, skip: str | None = None
    ) -> list[np.ndarray]:
        """Signed distances of world point sets, set k with the joints at ``qs[k]`` (default:
        every set at the instance's joints), to every shape not on link ``skip``."""
        if qs is None:
            qs = np.tile(self.inst.q, (len(points), 1))
        sizes = [len(p) for p in points]
        names = [n for n in self.names if self.tree.shapes[n]["link"] != skip]
        if not names or not sum(sizes):
            return [np.full(s, np.inf) for s in sizes]
        links = {self.tree.shapes[n]["link"] for n in names}
        own = bool(np.all(qs == self.inst.q))  # every set at the instance's joints
        motions = {
            link: np.broadcast_to(self._own_motion(link), (len(qs), 4, 4))
            if own
            else np.linalg.inv(self._link_poses(link, qs) @ self.rest[link])
            for link in links
        }  # (K, 4, 4) per link: world -> the link's frame at rest (concept frame, q = 0)
        local = {  # the points in each link's rest frame, shared by the link's shapes
            link: np.concatenate([p @ m[:3, :3].T + m[:3, 3] for p, m in zip(points, inv)])
            for link, inv in motions.items()
        }
        best = np.full(sum(sizes), np.inf)
        for name in names:
            at = local[self.tree.shapes[name]["link"]]
            best = np.minimum(best, self._shape(name, self.placements[name], at))
        return np.split(best, np.cumsum(sizes)[:-1])

    def _shape(self, name: str, place: np.ndarray, points: np.ndarray) -> np.ndarray:
        """``ShapeTree.sdf`` without re-validating the arguments on every call (the tree
        validated them once): this query runs many times per rank call."""
        s = self.tree.shapes[name]
        if s["primitive"] in ("union", "difference"):
            dists = [
                self._shape(op, place @ self.tree.relative(op), points) for op in s["operands"]
            ]
            if s["primitive"] == "union":
                return np.min(dists, axis=0)
            return np.maximum(dists[0], -np.min(dists[1:], axis=0))
        inv = self._inv.get(name)  # a shape sits at one place in the scene: invert it once
        if inv is None:
            inv = self._inv[name] = np.linalg.inv(place)
        local = points @ inv[:3, :3].T + inv[:3, 3]
        with np.errstate(invalid="ignore", divide="ignore"):
            d = FORMULAS[s["primitive"]](
                NumpyOps, local[:, 0], local[:, 1], local[:, 2], self.tree.params(name)
            )
        return np.asarray(d, dtype=float)

    def deepest(
        self,
        clouds: list[Cloud],
        poses: list[np.ndarray],
        qs: np.ndarray,
        skip: str | None = None,
    ) -> list[tuple[float, str]]:
        """Per cloud placed at its pose with the joints at its row of ``qs``: the deepest
        penetration (m, 0 when clear by more than ``CLEAR``) into a shape not on link ``skip``,
        and the box it happens in. Clusters whose centre lies farther outside than their radius
        less ``CLEAR`` are skipped."""
        centres = self.sdf([in_world(c.centres, p) for c, p in zip(clouds, poses)], qs, skip)
        near = [d - c.radii <= -CLEAR for c, d in zip(clouds, centres)]
        picked = [c.points[m[c.owner]] if len(c.points) else c.points for c, m in zip(clouds, near)]
        d = self.sdf([in_world(p, pose) for p, pose in zip(picked, poses)], qs, skip)
        out = []
        for c, m, dk in zip(clouds, near, d):
            if not len(dk):
                out.append((0.0, ""))
                continue
            i = int(np.argmin(dk))
            parts = [c.parts[j] for j in np.flatnonzero(m[c.owner])]
            out.append((max(0.0, -float(dk[i])), parts[i]))
        return out

    # -- the reverse check: the part's surface inside the hand's boxes
    def leaves(self) -> list[Leaf]:
        """Every thin primitive whose surface can be outer (a difference's first operand, a
        union's operands), with its bounding sphere at the instance's joints; cached."""
        if self._leaves is None:
            found: list[tuple[str, str, np.ndarray]] = []
            for name in self.names:
                self._collect(name, self.placements[name], found)
            leaves = (self._leaf(i, *f) for i, f in enumerate(found))
            self._leaves = [leaf for leaf in leaves if leaf is not None]
        return self._leaves

    def _collect(
        self, name: str, place: np.ndarray, out: list[tuple[str, str, np.ndarray]]
    ) -> None:
        s = self.tree.shapes[name]
        if s["primitive"] in ("union", "difference"):
            ops = s["operands"] if s["primitive"] == "union" else s["operands"][:1]
            for op in ops:
                self._collect(op, place @ self.tree.relative(op), out)
            return
        out.append((name, s["link"], place))

    def _leaf(self, index: int, name: str, link: str, place: np.ndarray) -> Leaf | None:
        primitive = self.tree.shapes[name]["primitive"]
        params = self.tree.params(name)
        area = surface_area(primitive, params)
        if not area > 0 or 2 * volume(primitive, params) / area > THIN:
            return None
        world = np.linalg.inv(self._own_motion(link)) @ place  # world <- primitive, at inst.q
        lo, hi = bounds(primitive, params)
        centre = world[:3, :3] @ ((lo + hi) / 2) + world[:3, 3]
        radius = float(np.linalg.norm(hi - lo)) / 2
        return Leaf(link, primitive, params, world, index, area, centre, radius)

    def surface(self, leaf: Leaf) -> tuple[np.ndarray, np.ndarray]:
        """The leaf's samples on the scene's outer surface (not inside another shape, not
        carved away by a difference), with their outward normals; drawn on first use."""
        if leaf.points is None or leaf.normals is None:
            k = int(np.clip(leaf.area / SURFACE_SPACING**2, SURFACE_MIN, SURFACE_MAX))
            rng = np.random.default_rng(leaf.index)
            pts, nrm = sample_surface(leaf.primitive, leaf.params, k, rng)
            pts = np.asarray(pts) @ leaf.world[:3, :3].T + leaf.world[:3, 3]
            nrm = np.asarray(nrm) @ leaf.world[:3, :3].T
            kept = np.abs(self.sdf([pts])[0]) <= SURFACE_ON
            leaf.points, leaf.normals = pts[kept], nrm[kept]
        return leaf.points, leaf.normals

    def inside(
        self, boxes: Boxes, pose: np.ndarray, q: np.ndarray | None = None, skip: str | None = None
    ) -> tuple[float, str]:
        """How deep the part reaches into ``boxes`` placed at ``pose`` (m; 0 if no surface
        sample lies inside one by more than ``CLEAR``) and in which box, the joints at ``q``
        (default: the instance's). Only links that stand where they stand at the instance's
        joints are sampled, and none on link ``skip``; a sample inside a box is followed along
        its inward normal (``PROBES`` points up to its distance from the box's faces) and the
        deepest signed distance there is the depth."""
        if not len(boxes.parts):
            return 0.0, ""
        q = self.inst.q if q is None else np.asarray(q, float)
        moved = set() if np.all(q == self.inst.q) else self._moved(q)
        mid, radius = boxes.reach()
        centre = pose[:3, :3] @ mid + pose[:3, 3]
        pts, nrm = [], []
        for leaf in self.leaves():
            if leaf.link == skip or leaf.link in moved:
                continue
            if np.linalg.norm(leaf.centre - centre) > radius + leaf.radius:
                continue
            p, n = self.surface(leaf)
            near = np.linalg.norm(p - centre, axis=1) <= radius
            pts.append(p[near])
            nrm.append(n[near])
        if not pts or not sum(map(len, pts)):
            return 0.0, ""
        points, normals = np.concatenate(pts), np.concatenate(nrm)
        world = pose @ boxes.poses  # (K, 4, 4)
        rot = world[:, :3, :3]
        # each point in each box's frame in one product: p R_k - c_k R_k, (n, K, 3)
        offsets = np.einsum("kj,kji->ki", world[:, :3, 3], rot)
        local = points @ rot.transpose(1, 0, 2).reshape(3, -1) - offsets.reshape(-1)
        local = local.reshape(len(points), len(rot), 3)
        room = (boxes.halves[None] - np.abs(local)).min(axis=2).T  # (K, n): < 0 outside
        k_idx, n_idx = np.nonzero(room > CLEAR)
        if not len(k_idx):
            return 0.0, ""
        order = np.argsort(-room[k_idx, n_idx])[:256]  # the deepest few hundred suffice
        k_idx, n_idx = k_idx[order], n_idx[order]
        steps = np.arange(1, PROBES + 1) / PROBES
        along = room[k_idx, n_idx][:, None] * steps[None, :]  # (c, PROBES)
        probes = points[n_idx][:, None, :] - normals[n_idx][:, None, :] * along[:, :, None]
        d = self.sdf([probes.reshape(-1, 3)], q[None, :], skip)[0].reshape(len(n_idx), PROBES)
        depth = -d.min(axis=1)
        i = int(np.argmax(depth))
        return max(0.0, float(depth[i])), boxes.parts[int(k_idx[i])]

    def _moved(self, q: np.ndarray) -> set[str]:
        """The links that stand elsewhere with the joints at ``q`` than at the instance's."""
        key = q.tobytes()
        if key not in self._moved_at:
            out = set()
            for link in {leaf.link for leaf in self.leaves()}:
                here = self._link_poses(link, self.inst.q[None, :])[0]
                there = self._link_poses(link, q[None, :])[0]
                if not np.allclose(here, there, atol=1e-9):
                    out.add(link)
            self._moved_at[key] = out
        return self._moved_at[key]

    def _own_motion(self, link: str) -> np.ndarray:
        """World -> the link's rest frame at the instance's own joints (computed once)."""
        if link not in self._own:
            q = self.inst.q[None, :]
            self._own[link] = np.linalg.inv(self._link_poses(link, q) @ self.rest[link])[0]
        return self._own[link]

    def _link_poses(self, link: str, qs: np.ndarray) -> np.ndarray:
        if qs.shape[1] == 0:  # nothing moves: the same pose at every state
            return np.broadcast_to(self.kin.link_pose(link), (len(qs), 4, 4))
        poses = np.asarray(self.kin.link_pose(link, qs), float)
        return poses.reshape(len(qs), 4, 4)


@dataclass
class Leaf:
    """One thin primitive of the scene: where it is (world <- primitive, at the instance's
    joints), its bounding sphere, and its samples on the outer surface once drawn."""

    link: str
    primitive: str
    params: dict[str, Any]
    world: np.ndarray
    index: int  # its sampling seed
    area: float
    centre: np.ndarray
    radius: float
    points: np.ndarray | None = None
    normals: np.ndarray | None = None


def in_world(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Hand-frame points placed at a world pose."""
    return points @ pose[:3, :3].T + pose[:3, 3]
