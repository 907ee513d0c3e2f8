"""``eac.estimate``: a concept's parameters, joints and pose from a partial cloud of it.

The analytic fit (``perception.fit``) from its own global start, or from a learned estimate
(``init``). Bad clouds are refused with ``PointCloudError`` (empty, not (N, 3), NaN or inf,
fewer than ``MIN_POINTS``); a cloud that is not of this concept still gets an ``Estimate``, but
with its residual and a low confidence, so a caller can refuse it instead of acting on it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from grace_dsl.perception.errors import PointCloudError
from grace_dsl.perception.fit import CAUCHY, FitResult, fit
from grace_dsl.perception.labels import check_labels, subsample
from grace_dsl.perception.types import Estimate
from grace_dsl.perception.views import join_params, split_params
from grace_dsl.runtime.library import Concept

MIN_POINTS = 32
MAX_POINTS = 768  # the fit's cost grows with the points; more add little at 2 mm noise
# a labelled cloud is kept up to this: its free space is read from the full outline
MAX_LABELLED = 20000
NOISE_FLOOR = 0.0025  # m: a residual below this is what a 2 mm sensor gives on the right model
FULL_COVER = 128  # points: fewer lower the confidence in proportion


def check_cloud(points: Any) -> np.ndarray:
    """``points`` as a finite (N, 3) float array with N >= MIN_POINTS, or ``PointCloudError``."""
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise PointCloudError(f"points must be an (N, 3) array of numbers ({exc})") from None
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise PointCloudError(f"points must have shape (N, 3), got {pts.shape}")
    if len(pts) == 0:
        raise PointCloudError("the cloud is empty: segment the part first (no pixels matched)")
    if not np.all(np.isfinite(pts)):
        bad = int((~np.isfinite(pts).all(axis=1)).sum())
        raise PointCloudError(
            f"{bad} of {len(pts)} points are NaN or infinite: drop the pixels with no depth"
        )
    if len(pts) < MIN_POINTS:
        raise PointCloudError(
            f"{len(pts)} points are too few to fit a concept (at least {MIN_POINTS}): move the "
            "camera nearer or widen the mask"
        )
    return pts


def confidence(residual: float, inliers: float, n_points: int, parts: float = 1.0) -> float:
    """In [0, 1]: falls with the residual beyond the sensor's noise, with the share of points
    off the surface, with few points, and (labelled fits) with the share of the worst part's
    points off that part's own shapes: a fit that lays a box's front on its back, or a handle
    beside its points, is wrong however well the union of shapes fits the cloud."""
    fit_term = math.exp(-max(0.0, residual - NOISE_FLOOR) / NOISE_FLOOR)
    cover = min(1.0, n_points / FULL_COVER)
    return float(np.clip(inliers**2 * parts**2 * fit_term * cover, 0.0, 1.0))


def estimate(
    concept: Concept | str,
    points: Any = None,
    *,
    pose_hint: Any = None,
    init: Estimate | Mapping[str, Any] | None = None,
    camera: Any = None,
    seed: int = 0,
    labels: Any = None,
    looks: Any = None,
    starts: Sequence[Estimate] = (),
) -> Estimate:
    """Estimate ``concept`` from ``points`` (N, 3), metres, in the camera frame (or give
    ``camera``, the camera's position in the points' frame).

    ``labels``: per point, the name of the part it shows (a sequence of N str: a link such as
    ``drawer``, a part such as ``handle``, a shape such as ``handle.bar``, or ``""`` for none;
    ``perception.labels``, ``labelled_points`` builds both from clouds per part). Each point
    is then measured against its own part, which fixes a handle's place and a box's facing.
    Wrong length or an unknown name raises ``LabelError``.

    ``pose_hint``: a 4x4 concept pose near the truth (skips the rotation search). ``init``: a
    learned ``Estimate`` (its parameters, pose and joints start the fit) or parameter values
    (``split_params`` names like ``front[0]``, or ``instantiate`` names).

    ``looks``: instead of ``points``, several ``perception.looks.Look(points, camera, labels)``
    in one shared frame, each with its camera's pose, fitted at once (free space and outline
    per camera); the pose is then the concept's in that frame, and ``starts`` (estimates in
    that frame) are screened with the hint (``perception.looks.estimate_looks``)."""
    start = time.perf_counter()
    if isinstance(concept, str):
        from grace_dsl.runtime.library import load_library

        concept = load_library()[concept]
    if looks is not None or points is None:
        from grace_dsl.perception.looks import LookError, estimate_looks

        if points is not None or camera is not None or labels is not None:
            raise LookError(
                "give points (with camera, labels) or looks, not both: a Look carries its own "
                "points, camera and labels"
            )
        if looks is None:
            raise LookError("give the points (N, 3) or looks=[Look(points, camera, labels)]")
        return estimate_looks(
            concept, looks, pose_hint=pose_hint, init=init, starts=starts, seed=seed
        )
    pts = check_cloud(points)
    parts = None if labels is None else check_labels(labels, len(pts))
    if parts is None:
        if len(pts) > MAX_POINTS:
            pts = pts[np.random.default_rng(seed).choice(len(pts), MAX_POINTS, replace=False)]
    elif len(pts) > MAX_LABELLED:  # the labelled fit subsamples per part itself
        keep = subsample(parts, MAX_LABELLED, np.random.default_rng(seed))
        pts, parts = pts[keep], parts[keep]
    params, joints, source = None, None, "fit"
    if isinstance(init, Estimate):
        params = join_params(concept, init.params, dict(init.discrete))
        joints = dict(init.joints)
        pose_hint = init.pose if pose_hint is None else pose_hint
        source = "learned+fit"
    elif init is not None:
        names = {s.name for s in concept.params}
        given = dict(init)
        params = given if set(given) <= names else join_params(concept, given, {})
        source = "learned+fit"
    hint = None if pose_hint is None else np.asarray(pose_hint, float).reshape(4, 4)
    cam = None if camera is None else np.asarray(camera, float).reshape(3)
    result = fit(
        concept,
        pts,
        camera=cam,
        pose_hint=hint,
        init=params,
        init_joints=joints,
        seed=seed,
        labels=parts,
    )
    return from_fit(concept, result, len(pts), source, start)


def from_fit(
    concept: Concept, result: FitResult, points: int, source: str, start: float
) -> Estimate:
    """The ``Estimate`` of a fit of ``points`` points begun at ``start`` (``perf_counter``)."""
    floats, discrete = split_params(concept, result.params)
    spread = (
        {}
        if result.spread is None
        else {k: float(v) for k, v in zip(floats, result.spread, strict=True)}
    )
    return Estimate(
        concept=concept.name,
        params=floats,
        pose=result.pose,
        joints=result.joints,
        residual=result.residual,
        confidence=confidence(result.residual, result.inliers, points, result.part_inliers),
        seconds=time.perf_counter() - start,
        source=source,
        discrete=discrete,
        spread=spread,
    )


__all__ = ["CAUCHY", "MIN_POINTS", "check_cloud", "confidence", "estimate"]
