"""A part-aware global start for the fit: the object's facing from the planes it shows.

Why: the fit stays in the basin it starts in, and a similarity ICP of a partial cloud against
the default instance picks wrong rotations and scales on large objects (a cabinet's front, top
and side are all planes). Two facts fix the rotation instead of searching for it: a camera held
level (no roll: its x axis is horizontal, as ``camera.look_at`` and a robot's head camera are)
sees the world's up direction in the plane of its y and z axes, and the concept's front (+z,
§6) is a vertical plane facing the camera. So every large vertical plane in the cloud (RANSAC,
normal turned toward the camera, tilted toward the image's bottom, which a horizontal top is
not) gives one rotation hypothesis: z its normal, y the up direction perpendicular to it and to
the camera's x axis. The translation then comes from a translation-only ICP of the cloud against
the surface of the start instance that faces the camera (its back would pull the cloud in), and
the hypotheses (planes times joint states) are ranked by that ICP's trimmed error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.library import Concept
from grace_dsl.runtime.verify import draw_params

PLANE_TOLERANCE = 0.005  # m: a point within this of a plane lies on it (2 mm depth noise)
PLANE_SHARE = 0.08  # a plane must hold this share of the points to be a facing hypothesis
PLANE_TRIES = 300
MAX_PLANES = 3
MAX_AZIMUTH = math.radians(80)  # a front seen more obliquely than this is a side
MIN_TILT = 0.05  # a front's normal points at least this far toward the image's bottom (+y)
MODEL_POINTS = 1500
ICP_POINTS = 384
ICP_STEPS = 12
PROBES = 4000  # surface samples that test whether a parameter moves a surface
DRAWS = 3  # random draws of the scalar lengths at the best facing


@dataclass(frozen=True)
class Plane:
    """A plane the cloud shows: unit normal toward the camera, a point on it, its inliers."""

    normal: np.ndarray
    point: np.ndarray
    inliers: np.ndarray  # indices into the cloud


def facing_planes(
    points: np.ndarray, camera: np.ndarray | None = None, seed: int = 0
) -> list[Plane]:
    """The large planes of ``points`` (camera frame) that could be the object's front, largest
    first: each found by RANSAC on what the earlier ones left, normal toward ``camera``."""
    cam = np.zeros(3) if camera is None else np.asarray(camera, float)
    rng = np.random.default_rng(seed)
    left = np.arange(len(points))
    out: list[Plane] = []
    need = max(16, int(PLANE_SHARE * len(points)))
    for _ in range(MAX_PLANES + 2):  # a horizontal top found on the way is skipped
        if len(left) < need or len(out) >= MAX_PLANES:
            break
        plane = _ransac(points[left], rng)
        if plane is None:
            break
        normal, point, on = plane
        if on.sum() < need:
            break
        if normal @ (cam - point) < 0:
            normal = -normal
        if normal[1] > MIN_TILT and _azimuth(normal, cam - point) <= MAX_AZIMUTH:
            out.append(Plane(normal, point, left[on]))
        left = left[~on]
    return out


def _azimuth(normal: np.ndarray, toward: np.ndarray) -> float:
    """Angle (rad) about the vertical between a front's normal and the direction to the camera:
    a robot looks at an object's front, not along its side (views are drawn within 70 deg)."""
    up = upright_rotation(normal)[:, 1]
    flat = toward - (toward @ up) * up
    n = float(np.linalg.norm(flat))
    return math.acos(float(np.clip(flat @ normal / n, -1.0, 1.0))) if n > 1e-9 else 0.0


def _ransac(
    pts: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The plane with the most points within ``PLANE_TOLERANCE``, refit by least squares."""
    if len(pts) < 3:
        return None
    tri = pts[rng.integers(0, len(pts), (PLANE_TRIES, 3))]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(normals, axis=1)
    ok = norm > 1e-9
    if not ok.any():
        return None
    normals, tri = normals[ok] / norm[ok, None], tri[ok]
    dist = np.abs((pts[None, :, :] - tri[:, None, 0, :]) @ normals[..., None])[..., 0]
    counts = (dist < PLANE_TOLERANCE).sum(axis=1)
    best = int(np.argmax(counts))
    on = dist[best] < PLANE_TOLERANCE
    centre = pts[on].mean(axis=0)
    normal = np.linalg.svd(pts[on] - centre, full_matrices=False)[2][
        -1
    ]  # least squares over the inliers
    on = np.abs((pts - centre) @ normal) < PLANE_TOLERANCE
    return normal, centre, on


def upright_rotation(normal: np.ndarray, right: np.ndarray | None = None) -> np.ndarray:
    """The concept's rotation in the camera frame when its front faces ``normal``: y the up
    direction perpendicular to the normal and to the camera's horizontal axis ``right``."""
    x_cam = np.array([1.0, 0.0, 0.0]) if right is None else np.asarray(right, float)
    z = normal / np.linalg.norm(normal)
    y = np.cross(z, x_cam)
    y /= np.linalg.norm(y)
    if y[1] > 0:  # up is toward the image's top (-y)
        y = -y
    return np.stack([np.cross(y, z), y, z], axis=1)


def feasible_instance(concept: Concept, params: Mapping[str, Any]) -> Instance:
    """An instance at ``params``, or, when they break a requirement (a start from a network or
    a scaled default can), at the first of them pulled toward the defaults that does not."""
    try:
        return concept.instantiate(params=params)
    except ParameterError:
        pass
    defaults = concept.instantiate().params
    for a in (0.9, 0.75, 0.5, 0.25):
        mixed = dict(params)
        for s in concept.params:
            if s.kind in ("num", "vec") and s.name in params:
                v = np.asarray(defaults[s.name], float) + a * (
                    np.asarray(params[s.name], float) - np.asarray(defaults[s.name], float)
                )
                mixed[s.name] = float(v) if s.kind == "num" else tuple(map(float, v))
        try:
            return concept.instantiate(params=mixed)
        except ParameterError:
            continue
    return concept.instantiate(
        params={k: v for k, v in params.items() if k not in defaults}
        | {k: defaults[k] for k in defaults if k in params}
    )


def facing_model(
    concept: Concept,
    params: Mapping[str, Any],
    joints: Mapping[str, float],
    view: np.ndarray,
    seed: int = 0,
) -> np.ndarray:
    """Surface samples (concept frame) of the instance that face the direction ``view`` (unit,
    concept frame, from the object toward the camera)."""
    pts, normals = _surface(concept, params, joints, seed)
    keep = normals @ view > 0.1
    return pts[keep] if keep.sum() >= 32 else pts


def _surface(
    concept: Concept, params: Mapping[str, Any], joints: Mapping[str, float], seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Surface samples and normals of the instance, the last few kept: every facing plane
    starts from the same unsized instance, and sampling it costs tens of milliseconds."""
    key = (concept, repr(sorted(params.items())), repr(sorted(joints.items())), seed)
    if key not in _SURFACES:
        inst = concept.instantiate(params=dict(params))
        if joints:
            inst = inst.with_joints(dict(joints))
        _SURFACES[key] = inst.sample_surface_with_normals(MODEL_POINTS, seed=seed)
        while len(_SURFACES) > 8:
            del _SURFACES[next(iter(_SURFACES))]
    return _SURFACES[key]


_SURFACES: dict[tuple[Concept, str, str, int], tuple[np.ndarray, np.ndarray]] = {}


def icp_translation(
    data: np.ndarray, model: np.ndarray, rot: np.ndarray, steps: int = ICP_STEPS
) -> tuple[np.ndarray, float]:
    """Translation of the concept (rotation ``rot`` fixed) that lays ``model`` (concept frame)
    over ``data`` (camera frame): trimmed nearest-point ICP from the centroids. Returns (the
    translation, the trimmed RMS distance)."""
    tree = cKDTree(model)
    local = data @ rot  # camera -> concept rotation, before the translation
    shift = model.mean(axis=0) - local.mean(axis=0)  # concept point = local + shift
    err = math.inf
    for _ in range(steps):
        dist, j = tree.query(local + shift)
        keep = dist <= np.quantile(dist, 0.8)
        shift = shift + (model[j[keep]] - (local[keep] + shift)).mean(axis=0)
        err = float(np.sqrt(np.mean(dist[keep] ** 2)))
    return -rot @ shift, err  # p_cam = rot @ (p_concept - shift)


def extent_scales(data: np.ndarray, model: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Per-axis scales (concept frame) that give ``model``'s facing surface the extent of
    ``data`` (camera frame, turned by ``rot``): 2-98 percentiles, so a few stray points do not
    count. A cabinet's width, height and depth are independent, and a nearest-point ICP barely
    moves a scale when the cloud covers part of the model."""
    local = data @ rot
    lo, hi = np.percentile(local, [2, 98], axis=0)
    mlo, mhi = np.percentile(model, [2, 98], axis=0)
    return np.clip((hi - lo) / np.maximum(mhi - mlo, 1e-3), 0.3, 3.0)


def axis_scaled(concept: Concept, base: Mapping[str, Any], scale: np.ndarray) -> dict[str, Any]:
    """``base`` with each length vector's component k multiplied by ``scale[k]`` (a size's
    width, height and depth lie along the concept's x, y and z), clipped to its range."""
    out = dict(base)
    for s in concept.params:
        if s.kind == "vec" and s.dim == "length" and s.size == 3 and s.lo is not None:
            v = np.clip(np.asarray(base[s.name], float) * scale, s.lo, s.hi)
            out[s.name] = tuple(map(float, v))
    return out


def plane_starts(
    concept: Concept,
    points: np.ndarray,
    params: Mapping[str, Any],
    joint_states: list[dict[str, float]],
    camera: np.ndarray | None = None,
    seed: int = 0,
    draws: int = DRAWS,
) -> list[tuple[float, np.ndarray, dict[str, Any], dict[str, float]]]:
    """Starts for the fit, best first, as ``fit.global_init`` gives them: (ICP error, concept
    pose in the points' frame, parameters, joints); empty when no plane could be a front.
    ``draws`` random draws of the scalar lengths follow the discrete variants of the best."""
    planes = facing_planes(points, camera, seed)
    if not planes:
        return []
    cam = np.zeros(3) if camera is None else np.asarray(camera, float)
    rng = np.random.default_rng(seed)
    data = points[rng.choice(len(points), min(ICP_POINTS, len(points)), replace=False)]
    toward = cam - points.mean(axis=0)
    toward /= max(float(np.linalg.norm(toward)), 1e-9)
    best: dict[int, list[tuple[float, np.ndarray, dict[str, Any], dict[str, float]]]] = {}
    for state in joint_states:
        for plane in planes:
            rot = upright_rotation(plane.normal)
            view = rot.T @ toward
            try:
                model = facing_model(concept, params, state, view, seed)
                sized = axis_scaled(concept, params, extent_scales(data, model, rot))
                sized = dict(feasible_instance(concept, sized).params)
                model = facing_model(concept, sized, state, view, seed)
            except ParameterError:
                continue
            t, err = icp_translation(data, model, rot)
            pose = np.eye(4)
            pose[:3, :3], pose[:3, 3] = rot, t
            best.setdefault(id(plane), []).append((err, pose, sized, dict(state)))
    # each plane's best joint state first (a learned start is screened against the first two,
    # which must be two facings when there are two), variants of the best, then the rest
    ranked = [sorted(v, key=lambda s: s[0]) for v in best.values()]
    firsts = sorted((r[0] for r in ranked), key=lambda s: s[0])
    rest = sorted((s for r in ranked for s in r[1:]), key=lambda s: s[0])
    if not firsts:
        return []
    err, pose, top, state = firsts[0]
    others = [(err, pose, v, state) for v in variants(concept, top, rng, draws)]
    return firsts + others + rest


def variants(
    concept: Concept, params: Mapping[str, Any], rng: np.random.Generator, draws: int = DRAWS
) -> list[dict[str, Any]]:
    """Other starts at the same facing and size: each other value of the discrete parameters
    (a hinge on the other side puts the handle at the other edge; the fit keeps discrete values
    fixed), then ``draws`` random draws of the scalar lengths (where the handle sits and how
    long it is: its points lie beyond the robust loss's reach when the start is far)."""
    out: list[dict[str, Any]] = []
    for s in concept.params:
        if s.kind == "choice" and s.choices:
            out += [dict(params) | {s.name: c} for c in s.choices if c != params[s.name]]
        elif s.kind == "bool":
            out.append(dict(params) | {s.name: not params[s.name]})
    unseen = shape_free(concept)
    for _ in range(draws):
        drawn = draw_params(concept, rng)
        mixed = dict(params)
        for s in concept.params:
            if s.kind == "num" and s.lo is not None and s.name not in unseen:
                mixed[s.name] = drawn[s.name]
        out.append(mixed)
    feasible = []
    for v in out:
        try:
            feasible.append(dict(feasible_instance(concept, v).params))
        except ParameterError:
            continue
    return feasible


@lru_cache(maxsize=64)
def _shape_free(concept: Concept) -> frozenset[str]:
    inst = concept.instantiate()
    ref = inst.sample_surface(PROBES, seed=0)
    free = set()
    for s in concept.params:
        if s.kind != "num" or s.lo is None:
            continue
        span, moved = s.hi - s.lo, False
        base = float(inst.params[s.name])
        for value in (base + 0.1 * span, base - 0.1 * span, s.lo, s.hi):
            if not s.lo <= value <= s.hi:
                continue
            try:
                other = concept.instantiate(params={s.name: float(value)})
            except ParameterError:
                continue
            # a surface that moved leaves the other's samples off this one's surface
            off = max(
                np.abs(inst.sdf(other.sample_surface(PROBES, seed=0))).max(),
                np.abs(other.sdf(ref)).max(),
            )
            if off > 1e-5:
                moved = True
                break
        if not moved:
            free.add(s.name)
    return frozenset(free)


def shape_free(concept: Concept) -> frozenset[str]:
    """Scalar parameters that change no surface of the default instance at its joints (a
    drawer's ``travel`` only bounds its slide): no view shows them, so an estimate can only
    keep them at its start (the dataset's typical value)."""
    return _shape_free(concept)


# -- restarts from the first stage's result: the local minima it is known to end in ----------

RESTART_JOINT = 0.02  # m or rad: a joint further than this from closed is restarted closed


def restarts(
    concept: Concept,
    pose: np.ndarray,
    params: Mapping[str, Any],
    joints: Mapping[str, float],
) -> list[tuple[np.ndarray, dict[str, Any], dict[str, float]]]:
    """Starts near a first-stage result (concept pose in the points' frame, parameters,
    joints) that leave the local minima it is known to end in, to be screened against it.

    - Joints closed: an open drawer's slide and its handle's standoff trade against each other
      (the bar stays on its points while the slide overshoots and the posts shrink); from the
      same pose and parameters with the joints closed the parts' own points pull the slide out
      to where the panel is, and the standoff follows."""
    out: list[tuple[np.ndarray, dict[str, Any], dict[str, float]]] = []
    limits = feasible_instance(concept, params).joint_limits() if joints else {}
    closed = {k: float(max(limits[k][0], -math.pi)) if k in limits else 0.0 for k in joints}
    if joints and max(abs(v - closed[k]) for k, v in joints.items()) > RESTART_JOINT:
        out.append((pose, dict(params), closed))
    return out
