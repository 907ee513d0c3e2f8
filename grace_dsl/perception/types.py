"""The values perception passes around: a view of a part, a segmenter, an estimate.

This module is the contract between the data generator, the learned estimator, the analytic
fit and the simulation benchmark's ``estimated`` mode; it imports nothing heavier than numpy.

Frames: a ``ViewSample``'s points are in the camera frame (OpenCV convention: +z forward along
the optical axis, +x right, +y down), metres. ``pose`` is the concept frame in that camera frame
(4x4, ``p_camera = pose @ p_concept``); ``camera_pose`` is the camera in the world frame, so a
point in the world is ``camera_pose @ p_camera``.

Parameters are SI (metres, radians) keyed by the concept's parameter names; only ``float``
parameters are estimated (a concept's ``int``/``choice``/``bool`` ones stay at the draw's values
and are carried in ``fixed``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

#: Shard files (``grace data gen``) are ``numpy.savez_compressed`` archives with these arrays,
#: one row per view, all views of one shard from one concept:
#:   points      (M, N, 3) float32  the target part's partial cloud, camera frame, N fixed per shard
#:   params      (M, P)    float64  the estimated parameters, in the order of ``param_names``
#:   poses       (M, 4, 4) float64  concept frame in the camera frame
#:   cameras     (M, 4, 4) float64  camera in the world frame
#:   joints      (M, J)    float64  joint values, in the order of ``joint_names``
#:   seeds       (M,)      int64    the seed each view was drawn from (replays the view alone)
#:   meta        ()        str      JSON: {"schema", "concept", "param_names", "joint_names",
#:                                   "fixed", "noise", "points_per_view", "part"}
SHARD_SCHEMA = "grace-eac.views/1"


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera: focal lengths and principal point in pixels, image size."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int


@dataclass(frozen=True)
class ViewSample:
    """One synthetic view: the target part's partial cloud with its ground truth."""

    concept: str
    points: np.ndarray  # (N, 3) camera frame
    params: dict[str, float]  # the estimated (float) parameters
    pose: np.ndarray  # (4, 4) concept frame in the camera frame
    camera_pose: np.ndarray  # (4, 4) camera in the world frame
    joints: dict[str, float]
    seed: int
    fixed: dict[str, object] = field(default_factory=dict)  # non-float parameters, as drawn
    part: str = ""  # the concept link the points belong to ("" for the whole instance)


@dataclass(frozen=True)
class Estimate:
    """What perception says about one part: its parameters, where it is, how sure it is.

    ``pose`` is the concept frame in the frame the points were given in. ``residual`` is the
    robust mean distance (m) from the observed points to the fitted surface; ``confidence`` in
    [0, 1] falls with the residual and with poor coverage, so a caller can refuse a bad fit
    instead of acting on it."""

    concept: str
    params: dict[str, float]
    pose: np.ndarray
    joints: dict[str, float]
    residual: float
    confidence: float
    seconds: float
    source: str = "fit"  # "learned", "fit" or "learned+fit"
    # the non-float parameters the fit chose (a hinge's side), when it chose them
    discrete: dict[str, object] = field(default_factory=dict)
    # one standard deviation (SI) of each estimated parameter, where the estimator can tell: a
    # parameter the view does not show (a drawer's travel, the depth behind a closed front) has
    # about its whole range here, and is a guess however close ``params`` happens to be
    spread: dict[str, float] = field(default_factory=dict)


class Segmenter(Protocol):
    """Image, depth and a text query -> a boolean mask (H, W) per named part it found.

    The default uses the renderer's ground-truth segmentation; an open-vocabulary model plugs in
    behind the same call. An empty dict means nothing matched the query."""

    def segment(self, rgb: np.ndarray, depth: np.ndarray, query: str) -> dict[str, np.ndarray]: ...
