"""Several looks fitted at once: clouds from different cameras, one set of parameters.

Why: one camera bounds a box only where its silhouette and its free space reach; a cabinet's
depth seen from the front, or its bottom seen from above, is a sliver of pixels, and a closed
drawer's back is not seen at all. A second camera from the side sees what the first could not.
Fitting each look alone and keeping the best throws that away; here every look's points join
one data term (each measured against its own part when labelled) and each camera's free space
and silhouette keep their own rays (``fit.labelled_fit``'s ``views``).

A ``Look`` is one camera's cloud in a frame all the looks share (the world), with that camera's
pose in the same frame, so the estimate's pose is the concept's in that frame too.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.labels import UNLABELLED, check_labels, subsample
from grace_dsl.perception.types import Estimate
from grace_dsl.perception.views import join_params
from grace_dsl.runtime.library import Concept

#: per look, as ``estimate``'s one cloud: the fit thins each look's labelled share itself
MAX_LOOK_POINTS = 20000
# m: a look's points must lie this far in front of its camera (a cloud left in the camera's
# own frame sits in front of the world origin, not of the camera's pose)
MIN_DEPTH = 0.05


class LookError(PerceptionError):
    """Looks that cannot be fitted together: none given, a camera that is not a pose, labels
    on some looks and not others, or points that are not in front of their camera."""


@dataclass(frozen=True)
class Look:
    """One camera's view: ``points`` (N, 3) in the frame shared by every look (the world),
    ``camera`` the camera's pose in that frame (4x4, ``p_shared = camera @ p_camera``, OpenCV
    axes: +z forward), ``labels`` one part name per point (as ``estimate``'s) or None."""

    points: Any
    camera: Any
    labels: Any = None


@dataclass(frozen=True)
class CheckedLook:
    """A ``Look`` validated: finite arrays, labels as str (``""`` where none were given)."""

    points: np.ndarray
    camera: np.ndarray  # (4, 4)
    labels: np.ndarray
    labelled: bool


def check_looks(looks: Any, seed: int = 0) -> list[CheckedLook]:
    """``looks`` validated, or ``LookError`` / ``PointCloudError`` / ``LabelError`` naming the
    look at fault. A look over ``MAX_LOOK_POINTS`` is thinned keeping every label's share."""
    from grace_dsl.perception.estimate import check_cloud

    if isinstance(looks, Look):
        looks = [looks]
    if not isinstance(looks, Sequence) or not looks:
        raise LookError("give a non-empty list of Look(points, camera, labels)")
    out = []
    for k, look in enumerate(looks):
        if not isinstance(look, Look):
            raise LookError(f"look {k} is a {type(look).__name__}, not a Look(points, camera)")
        pts = check_cloud(look.points)
        cam = _camera(look.camera, k)
        labelled = look.labels is not None
        labels = (
            check_labels(look.labels, len(pts))
            if labelled
            else np.full(len(pts), UNLABELLED, dtype=object).astype(str)
        )
        depth = (pts - cam[:3, 3]) @ cam[:3, 2]
        if float(np.median(depth)) < MIN_DEPTH:
            raise LookError(
                f"look {k}: its points lie behind its camera (median depth "
                f"{float(np.median(depth)):.3f} m along the camera's +z): give the points in "
                "the shared frame (camera @ p_camera) and the camera's pose in that frame"
            )
        if len(pts) > MAX_LOOK_POINTS:
            keep = subsample(labels, MAX_LOOK_POINTS, np.random.default_rng(seed + k))
            pts, labels = pts[keep], labels[keep]
        out.append(CheckedLook(pts, cam, labels, labelled))
    if len({c.labelled for c in out}) > 1:
        which = [k for k, c in enumerate(out) if not c.labelled]
        raise LookError(
            f"looks {which} have no labels while the others do: label every look (a point's "
            "part name, '' for none) or none of them"
        )
    return out


def _camera(camera: Any, k: int) -> np.ndarray:
    """A look's camera pose as a rigid 4x4, or ``LookError``."""
    try:
        cam = np.asarray(camera, dtype=float)
    except (TypeError, ValueError):
        raise LookError(f"look {k}: camera must be a 4x4 pose, got {camera!r}") from None
    if cam.shape != (4, 4) or not np.all(np.isfinite(cam)):
        raise LookError(
            f"look {k}: camera must be a finite 4x4 pose (the camera in the shared frame), "
            f"got shape {cam.shape}"
        )
    rot = cam[:3, :3]
    if not np.allclose(rot.T @ rot, np.eye(3), atol=1e-6) or np.linalg.det(rot) < 0:
        raise LookError(f"look {k}: the camera's rotation is not a rotation (orthonormal, det 1)")
    return cam


def estimate_looks(
    concept: Concept,
    looks: Any,
    *,
    pose_hint: Any = None,
    init: Estimate | Mapping[str, Any] | None = None,
    starts: Sequence[Estimate] = (),
    seed: int = 0,
) -> Estimate:
    """One estimate from every look: ``estimate(concept, looks=...)``. The pose is the concept
    in the looks' shared frame. Starts: ``pose_hint`` with ``init`` (an ``Estimate`` or
    parameter values, in that frame), each of ``starts`` (estimates in that frame: single
    looks' fits), or, when none is given, each look's fit alone in its camera's frame (its
    facing-plane starts), carried into the shared frame; the fused stages then screen them."""
    from grace_dsl.perception.estimate import estimate, from_fit
    from grace_dsl.perception.fit import labelled_fit

    start = time.perf_counter()
    checked = check_looks(looks, seed)
    params: dict[str, Any] | None = None
    joints: dict[str, float] | None = None
    hint = None if pose_hint is None else np.asarray(pose_hint, float).reshape(4, 4)
    source = "fit"
    if isinstance(init, Estimate):
        params = join_params(concept, init.params, dict(init.discrete))
        joints = dict(init.joints)
        hint = init.pose if hint is None else hint
        source = init.source if init.source != "fit" else source
    elif init is not None:
        names = {s.name for s in concept.params}
        given = dict(init)
        params = given if set(given) <= names else join_params(concept, given, {})
    extra = [_start(concept, e) for e in starts]
    if hint is None and not extra:  # each look alone, from its own camera: one start each
        for look in checked:
            inv = np.linalg.inv(look.camera)
            local = look.points @ inv[:3, :3].T + inv[:3, 3]
            named = list(look.labels) if look.labelled else None
            alone = estimate(concept, local, init=params, seed=seed, labels=named)
            extra.append(_start(concept, alone, look.camera))
    points = np.concatenate([c.points for c in checked])
    labels = np.concatenate([c.labels for c in checked])
    result = labelled_fit(
        concept,
        points,
        labels,
        camera=checked[0].camera[:3, 3],
        pose_hint=hint,
        init=params,
        init_joints=joints,
        seed=seed,
        views=[(c.points, c.camera[:3, 3]) for c in checked],
        starts=extra,
    )
    return from_fit(concept, result, len(points), source, start)


def _start(
    concept: Concept, est: Estimate, frame: np.ndarray | None = None
) -> tuple[np.ndarray, dict[str, Any], dict[str, float]]:
    """An estimate as a fit start (pose, parameters, joints), its pose carried by ``frame``."""
    pose = np.asarray(est.pose, float) if frame is None else frame @ np.asarray(est.pose, float)
    return pose, join_params(concept, est.params, dict(est.discrete)), dict(est.joints)


__all__ = ["Look", "LookError", "check_looks", "estimate_looks"]
