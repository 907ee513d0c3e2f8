"""Synthetic views of a concept: random instance, random joints, random camera, partial cloud.

Each view is a pure function of one integer seed (``draw_view``), so a dataset is the list of
its seeds and any view can be replayed alone; ``generate_views`` derives the seeds from the
concept's name and a dataset seed, which makes the arrays identical whatever the number of
workers. The camera looks at the instance from the upper hemisphere in front of it (a concept's
front is +z, §6: a view from behind sees no handle, so the azimuth is drawn within
``ViewConfig.azimuth`` of +z), from a distance at which the instance fills a random share of the
image, then the depth gets the sensor's noise and the target's pixels are back-projected and
resampled to a fixed number of points.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from grace_dsl.perception.camera import (
    DEFAULT_INTRINSICS,
    DepthNoise,
    back_project,
    fov_half,
    look_at,
)
from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.render import DepthRender, InstanceSDF, bounding_sphere, render
from grace_dsl.perception.types import Intrinsics, ViewSample
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.library import Concept
from grace_dsl.runtime.verify import draw_params

MIN_PIXELS = 64  # a view that shows fewer target pixels is drawn again
MAX_TRIES = 40  # draws of parameters (requirements) or of views before giving up
MIN_RANGE = 0.25  # m: RGB-D cameras see nothing nearer


@dataclass(frozen=True)
class ViewConfig:
    """How views are drawn: cloud size, sensor noise, camera and the ranges of its placement.

    ``elevation`` (rad) above the horizontal, ``azimuth`` (rad) either side of the concept's
    front (+z), ``fill`` the share of the image's smaller half-angle that the instance's
    bounding sphere takes, ``closed`` the share of views with every joint closed (the rest draw
    each joint uniformly in its range), ``part`` the link whose points are kept ("" for all)."""

    points: int = 1024
    noise: DepthNoise = field(default_factory=DepthNoise)
    intrinsics: Intrinsics = DEFAULT_INTRINSICS
    elevation: tuple[float, float] = (math.radians(10), math.radians(60))
    azimuth: float = math.radians(70)
    fill: tuple[float, float] = (0.45, 0.9)
    closed: float = 0.5
    part: str = ""


@dataclass(frozen=True)
class RenderedView:
    """A view with its images (what ``ViewSample`` drops): for pictures and segmentation."""

    sample: ViewSample
    render: DepthRender
    depth: np.ndarray  # the noisy depth the points came from
    instance: Instance
    # per point of ``sample``, the outermost shape it shows (``handle.bar``): part labels
    labels: tuple[str, ...] = ()


def float_params(concept: Concept) -> tuple[str, ...]:
    """The parameters an estimator predicts: the real-valued ones, vectors per component
    (``front[0]``...), in the concept's order (the columns of a shard's ``params``)."""
    names: list[str] = []
    for s in concept.params:
        if s.kind == "num":
            names.append(s.name)
        elif s.kind == "vec":
            names += [f"{s.name}[{k}]" for k in range(s.size)]
    return tuple(names)


def split_params(
    concept: Concept, values: dict[str, Any]
) -> tuple[dict[str, float], dict[str, Any]]:
    """A concept's parameter values as (estimated floats by ``float_params`` name, the rest)."""
    floats: dict[str, float] = {}
    fixed: dict[str, Any] = {}
    for s in concept.params:
        v = values[s.name]
        if s.kind == "num":
            floats[s.name] = float(v)
        elif s.kind == "vec":
            floats.update({f"{s.name}[{k}]": float(x) for k, x in enumerate(v)})
        else:
            fixed[s.name] = v
    return floats, fixed


def join_params(
    concept: Concept, floats: dict[str, float], fixed: dict[str, Any]
) -> dict[str, Any]:
    """The inverse of ``split_params``: values ``Concept.instantiate`` takes."""
    out: dict[str, Any] = dict(fixed)
    for s in concept.params:
        if s.kind == "num" and s.name in floats:
            out[s.name] = float(floats[s.name])
        elif s.kind == "vec" and f"{s.name}[0]" in floats:
            out[s.name] = tuple(float(floats[f"{s.name}[{k}]"]) for k in range(s.size))
    return out


def view_seed(concept: str, seed: int, index: int) -> int:
    """The seed of view ``index`` of a dataset drawn with ``seed`` (63 bits, stable)."""
    ss = np.random.SeedSequence([int(seed), int(index), zlib.crc32(concept.encode())])
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))


def random_instance(concept: Concept, rng: np.random.Generator, closed: float = 0.5) -> Instance:
    """An instance with parameters drawn in their typical ranges (redrawn until the
    requirements hold) and joints closed, or each uniform in its range."""
    last: Exception | None = None
    for _ in range(MAX_TRIES):
        try:
            inst = concept.instantiate(params=draw_params(concept, rng))
        except ParameterError as exc:  # RequirementError and ShapeError are ParameterErrors
            last = exc
            continue
        if rng.random() < closed:
            return inst
        joints = {}
        for name, (lo, hi) in inst.joint_limits().items():
            lo, hi = max(lo, -math.pi), min(hi, math.pi)  # a continuous joint turns freely
            joints[name] = float(rng.uniform(lo, hi))
        return inst.with_joints(joints) if joints else inst
    raise PerceptionError(
        f"{concept.name}: no parameter draw met its requirements in {MAX_TRIES} tries ({last})"
    )


def random_camera(
    centre: np.ndarray, radius: float, config: ViewConfig, rng: np.random.Generator
) -> np.ndarray:
    """A camera pose on the upper front hemisphere around ``centre``, looking near it."""
    elev = rng.uniform(*config.elevation)
    azim = rng.uniform(-config.azimuth, config.azimuth)
    fill = rng.uniform(*config.fill)
    dist = max(radius / math.tan(fov_half(config.intrinsics) * fill), radius + MIN_RANGE)
    direction = np.array(
        [math.cos(elev) * math.sin(azim), math.sin(elev), math.cos(elev) * math.cos(azim)]
    )
    target = centre + rng.uniform(-0.1, 0.1, 3) * radius
    return look_at(centre + dist * direction, target)


def render_view(concept: Concept, seed: int, config: ViewConfig | None = None) -> RenderedView:
    """View ``seed`` of ``concept`` with its images; ``draw_view`` keeps the sample only."""
    config = ViewConfig() if config is None else config
    rng = np.random.default_rng(seed)
    inst = random_instance(concept, rng, config.closed)
    if config.part and config.part not in inst.links:
        raise PerceptionError(
            f"{concept.name} has no link {config.part!r} (links: {', '.join(inst.links)})"
        )
    sdf, sphere = InstanceSDF(inst), bounding_sphere(inst)
    for _ in range(MAX_TRIES):
        camera = random_camera(sphere[0], sphere[1], config, rng)
        shot = render(inst, camera, config.intrinsics, sdf, sphere)
        depth = config.noise.apply(shot.depth, rng)
        mask = shot.mask([config.part] if config.part else None)
        cloud = back_project(depth, config.intrinsics, mask)  # row-major, as np.nonzero
        if len(cloud) >= MIN_PIXELS:
            break
    else:
        raise PerceptionError(
            f"{concept.name}: part {config.part or '(all)'} showed fewer than {MIN_PIXELS} "
            f"pixels in {MAX_TRIES} views"
        )
    pick = rng.choice(len(cloud), config.points, replace=len(cloud) < config.points)
    floats, fixed = split_params(concept, inst.params)
    sample = ViewSample(
        concept=concept.name,
        points=cloud[pick].astype(np.float32),
        params=floats,
        pose=np.linalg.inv(camera),  # concept frame (= world here) in the camera frame
        camera_pose=camera,
        joints=dict(inst.joints),
        seed=int(seed),
        fixed=fixed,
        part=config.part,
    )
    return RenderedView(sample, shot, depth, inst, _point_labels(shot, depth, mask, pick))


def _point_labels(
    shot: DepthRender, depth: np.ndarray, mask: np.ndarray, pick: np.ndarray
) -> tuple[str, ...]:
    """The shape each picked point shows, in ``back_project``'s order of the masked pixels."""
    if shot.shape_labels is None:
        return ()
    index = shot.shape_labels[np.nonzero((depth > 0) & mask)][pick]
    return tuple(shot.shapes[k] if k >= 0 else "" for k in index)


def draw_view(concept: Concept, seed: int, config: ViewConfig | None = None) -> ViewSample:
    """One view: a pure function of ``(concept, seed, config)``."""
    return render_view(concept, seed, config).sample


def generate_views(
    concept: Concept | str,
    n: int,
    seed: int = 0,
    *,
    points: int = 1024,
    noise: float = 0.002,
    config: ViewConfig | None = None,
    start: int = 0,
    progress: Callable[[int], None] | None = None,
) -> list[ViewSample]:
    """``n`` views of ``concept`` (a Concept or a standard-library name), views ``start`` to
    ``start + n - 1`` of the dataset ``seed``. ``points`` and ``noise`` (Gaussian depth sigma,
    m) set the config's fields when ``config`` is None; ``progress(k)`` is told each view."""
    if isinstance(concept, str):
        from grace_dsl.runtime.library import load_library

        concept = load_library()[concept]
    if config is None:
        config = ViewConfig(points=points, noise=DepthNoise(sigma=noise))
    check_config(config)
    out = []
    for i in range(start, start + n):
        out.append(draw_view(concept, view_seed(concept.name, seed, i), config))
        if progress is not None:
            progress(1)
    return out


def generate_labelled_views(
    concept: Concept | str,
    n: int,
    seed: int = 0,
    *,
    points: int = 1024,
    noise: float = 0.002,
    start: int = 0,
    every_pixel: bool = False,
) -> list[tuple[ViewSample, tuple[str, ...]]]:
    """The views ``generate_views`` draws (same seeds, same points), each with its points' part
    labels: the outermost shape each point shows, as the renderer segments it. With
    ``every_pixel`` the sample's points are every pixel of the view instead of the resample
    (same instance, camera and noise): what a segmenter hands on at the camera's resolution,
    where a cabinet's handle has tens of pixels rather than the few of a 1024-point resample."""
    if isinstance(concept, str):
        from grace_dsl.runtime.library import load_library

        concept = load_library()[concept]
    config = ViewConfig(points=points, noise=DepthNoise(sigma=noise))
    check_config(config)
    out = []
    for i in range(start, start + n):
        view = render_view(concept, view_seed(concept.name, seed, i), config)
        if every_pixel:
            mask = view.render.mask()
            every = back_project(view.depth, config.intrinsics, mask)
            labels = _point_labels(view.render, view.depth, mask, np.arange(len(every)))
            out.append((replace(view.sample, points=every.astype(np.float32)), labels))
        else:
            out.append((view.sample, view.labels))
    return out


def check_config(config: ViewConfig) -> None:
    """Refuse configurations no view can come from, naming the field."""
    if not (isinstance(config.points, int) and 1 <= config.points <= 1_000_000):
        raise PerceptionError(f"points must be an integer in [1, 1e6], got {config.points!r}")
    n = config.noise
    if not (0 <= n.sigma < 0.1 and 0 <= n.dropout < 1 and 0 <= n.flying <= 1):
        raise PerceptionError(
            f"noise: sigma in [0, 0.1) m, dropout in [0, 1), flying in [0, 1]; got {n}"
        )


def stack_views(views: Sequence[ViewSample], joints: Sequence[str]) -> dict[str, np.ndarray]:
    """Views of one concept as the arrays of a shard (``perception.types.SHARD_SCHEMA``);
    ``joints`` names the columns of ``joints`` (a joint a view's instance lacks reads 0)."""
    if not views:
        raise PerceptionError("no views to stack")
    names = tuple(views[0].params)
    return {
        "points": np.stack([v.points for v in views]).astype(np.float32),
        "params": np.array([[v.params[k] for k in names] for v in views], dtype=np.float64),
        "poses": np.stack([v.pose for v in views]).astype(np.float64),
        "cameras": np.stack([v.camera_pose for v in views]).astype(np.float64),
        "joints": np.array(
            [[v.joints.get(k, 0.0) for k in joints] for v in views], np.float64
        ).reshape(len(views), len(joints)),
        "seeds": np.array([v.seed for v in views], dtype=np.int64),
    }
