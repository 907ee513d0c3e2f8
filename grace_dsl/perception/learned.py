"""The learned estimator: a partial cloud -> a concept's parameters and a first pose.

Why it exists next to the analytic fit: the network answers in milliseconds from any view the
training data covered, which gives the fit a start inside the right basin; alone it is only as
good as its synthetic training. The pose comes from the network's pose head (the concept's
axes and its origin's offset from the centroid, in the cloud's frame); the residual is the
robust mean distance of the points to the predicted instance's surface, so a confident-looking
prediction on a cloud of the wrong object shows up as a large residual and a low confidence.

torch is imported when a network is built, never when this module is imported.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.perception.errors import ModelWeightsError
from grace_dsl.perception.train import check_cloud, normalize_cloud
from grace_dsl.perception.types import Estimate
from grace_dsl.perception.weights import WeightsFile, read_weights, shipped_path

#: A residual (m) of this size halves the confidence.
RESIDUAL_HALF = 0.004
RESIDUAL_POINTS = 256  # points the residual is measured on


class LearnedEstimator:
    """A loaded network with its normalization; ``predict`` turns clouds into estimates."""

    def __init__(self, weights: WeightsFile, concept: Any = None, threads: int = 1) -> None:
        import torch

        from grace_dsl.perception.point_transformer import ModelConfig, PointTransformer

        try:
            cfg = ModelConfig.from_dict(weights.config)
            model = PointTransformer(cfg)
            model.load_state_dict({k: torch.from_numpy(v) for k, v in weights.tensors.items()})
        except (TypeError, ValueError, RuntimeError) as exc:
            raise ModelWeightsError(
                f"{weights.path or weights.concept}: the tensors do not fit the network "
                f"their header describes ({exc})"
            ) from exc
        if cfg.n_params != len(weights.param_names):
            raise ModelWeightsError(f"{weights.path}: {cfg.n_params} heads for "
                                    f"{len(weights.param_names)} parameters")  # fmt: skip
        model.eval()
        self.weights, self.model, self.concept = weights, model, concept
        self.threads = threads  # one cloud is too small a job to split: more threads only wait
        if concept is not None:
            _check_concept(weights, concept)

    @staticmethod
    def load(concept: Any, path: str | Path | None = None) -> LearnedEstimator:
        """The estimator for ``concept`` (a Concept or its name) from ``path``, or from the
        weights the package ships for it."""
        name = concept if isinstance(concept, str) else concept.name
        file = shipped_path(name) if path is None else Path(path)
        if path is None and not file.is_file():
            raise ModelWeightsError(
                f"no shipped weights for {name}; train them with `grace train {name} -o FILE` "
                "and pass the file"
            )
        return LearnedEstimator(read_weights(file, name), None if isinstance(concept, str)
                                else concept)  # fmt: skip

    def predict_arrays(self, points: np.ndarray) -> tuple[dict[str, float], np.ndarray]:
        """Parameters (SI) and the concept frame in the cloud's frame (4x4), no checks."""
        import torch

        w = self.weights
        cloud, centroid = normalize_cloud(points, w.points, w.scale)
        before = torch.get_num_threads()
        torch.set_num_threads(self.threads)  # 20 ms on one thread, over 1 s on two busy cores
        try:
            with torch.no_grad():
                norm, pose = self.model(torch.from_numpy(cloud[None]))
        finally:
            torch.set_num_threads(before)
        values = w.lo + np.clip(norm[0].numpy().astype(float), -0.1, 1.1) * (w.hi - w.lo)
        params = {n: float(v) for n, v in zip(w.param_names, values, strict=True)}
        frame = np.eye(4)
        if pose is not None:
            p = pose[0].numpy().astype(float)
            frame[:3, :3] = _orthonormal(p[:3], p[3:6])
            frame[:3, 3] = centroid + p[6:9] * w.scale
        else:
            frame[:3, 3] = centroid
        return params, frame

    def predict(self, points: Any) -> Estimate:
        """An ``Estimate(source="learned")`` for one cloud (N, 3) in any frame; joints are the
        closed state (the fit estimates them)."""
        t0 = time.perf_counter()
        cloud = check_cloud(points)
        params, frame = self.predict_arrays(cloud)
        residual = self.residual(cloud, params, frame) if self.concept is not None else math.inf
        confidence = 0.0 if not math.isfinite(residual) else 0.5 ** (residual / RESIDUAL_HALF)
        return Estimate(
            concept=self.weights.concept,
            params=params,
            pose=frame,
            joints={},
            residual=residual,
            confidence=float(confidence),
            seconds=time.perf_counter() - t0,
            source="learned",
        )

    def residual(self, cloud: np.ndarray, params: dict[str, float], frame: np.ndarray) -> float:
        """Robust mean distance (m) of the points to the predicted instance's surface: the
        mean of the smaller 90 % of |sdf| over up to 256 of them (seeded); infinite when the
        prediction is no valid instance."""
        from grace_dsl.runtime.errors import GraceError

        if len(cloud) > RESIDUAL_POINTS:  # the mean needs no more; the sdf costs per point
            cloud = cloud[np.random.default_rng(0).choice(len(cloud), RESIDUAL_POINTS, False)]
        try:
            inst = self.concept.instantiate(params=join_floats(self.concept, params))
            d = np.abs(inst.sdf(_transform(np.linalg.inv(frame), cloud)))
        except GraceError:
            return math.inf
        d = np.sort(d)[: max(1, int(0.9 * len(d)))]
        return float(d.mean())


def estimate_learned(concept: Any, points: Any, weights: str | Path | None = None) -> Estimate:
    """``LearnedEstimator.load(concept, weights).predict(points)``, with the loaded network
    kept for the next call on the same concept and file (building it costs ~50 ms)."""
    key = (concept if isinstance(concept, str) else concept.name, str(weights), id(concept))
    est = _LOADED.get(key)
    if est is None or (not isinstance(concept, str) and est.concept is not concept):
        if len(_LOADED) >= 32:
            _LOADED.clear()
        est = _LOADED[key] = LearnedEstimator.load(concept, weights)
    return est.predict(points)


_LOADED: dict[tuple[str, str, int], LearnedEstimator] = {}


def join_floats(concept: Any, floats: dict[str, float]) -> dict[str, Any]:
    """The estimated floats (vector components as ``name[k]``) as instantiate's parameters;
    parameters not estimated keep their defaults."""
    out: dict[str, Any] = {}
    for spec in concept.params:
        if spec.kind == "vec" and f"{spec.name}[0]" in floats:
            out[spec.name] = tuple(float(floats[f"{spec.name}[{k}]"]) for k in range(spec.size))
        elif spec.name in floats:
            out[spec.name] = float(floats[spec.name])
    return out


def _check_concept(weights: WeightsFile, concept: Any) -> None:
    """The weights' parameters must all be the concept's (a renamed parameter means stale
    weights, which would otherwise predict into the wrong slot)."""
    if weights.concept != concept.name:
        raise ModelWeightsError(f"weights for {weights.concept} given for {concept.name}")
    known = set()
    for spec in concept.params:
        known.add(spec.name)
        known.update(f"{spec.name}[{k}]" for k in range(spec.size))
    stale = [n for n in weights.param_names if n not in known]
    if stale:
        raise ModelWeightsError(
            f"{weights.path}: {concept.name} has no parameter {', '.join(stale)}; retrain"
        )


def _orthonormal(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation whose x axis is along ``a`` and y axis along ``b``'s part orthogonal to it."""
    x = a / max(np.linalg.norm(a), 1e-9)
    b = b - x * float(x @ b)
    y = b / max(np.linalg.norm(b), 1e-9)
    return np.stack([x, y, np.cross(x, y)], axis=1)


def _transform(t: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ t[:3, :3].T + t[:3, 3]
