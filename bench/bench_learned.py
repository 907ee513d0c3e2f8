"""How well the shipped learned estimator reads concept parameters from held-out noisy views.

Run: ``.venv/bin/python bench/bench_learned.py [--concepts NAME ...] [--views N] [--data DIR]
[--out FILE] [--small | --smoke]`` (writes bench/results/learned.json). For each concept with
shipped weights: ``--views`` held-out synthetic views (dataset seed 1000, which no training set
uses; depth noise sigma 2 mm; 1024 points), or the shards under ``--data DIR/CONCEPT``, each
predicted by the network alone. Reported per concept: mean absolute error over length
parameters (mm) and angle parameters (deg), the share of (view, length parameter) pairs within
5 mm and of views with every length within 5 mm, the pose head's origin (mm) and rotation (deg)
errors, and milliseconds per cloud (network only, one torch thread). ``--small``: four concepts,
8 views; ``--smoke``: one concept, 3 views, as the test suite runs it.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

import grace_dsl as eac
from grace_dsl.perception.learned import LearnedEstimator
from grace_dsl.perception.train import load_shards
from grace_dsl.perception.views import generate_views
from grace_dsl.perception.weights import shipped_concepts

OUT = Path(__file__).parent / "results" / "learned.json"
HELD_OUT_SEED = 1000
SMALL = ("StraightHandle", "CabinetDrawer", "RoundKnob", "HingedCabinet")


def _dims(concept: Any, names: tuple[str, ...]) -> list[str]:
    """Each estimated parameter's dimension ("length" or "angle"), vector components too."""
    dims = {s.name: s.dim for s in concept.params}
    return [str(dims.get(n.split("[")[0], "")) for n in names]


def _rotation_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = (np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def evaluate(concept: Any, points: np.ndarray, params: np.ndarray, poses: np.ndarray,
             names: tuple[str, ...]) -> dict[str, Any]:  # fmt: skip
    """The estimator's errors on these views of ``concept``."""
    est = LearnedEstimator.load(concept)
    order = [est.weights.param_names.index(n) for n in names]
    dims = np.array(_dims(concept, names))
    preds, seconds, t_err, r_err = [], [], [], []
    est.predict_arrays(points[0].astype(float))  # warm-up: the first call pays allocation
    for cloud, pose in zip(points, poses, strict=True):
        t = time.perf_counter()
        p, frame = est.predict_arrays(cloud.astype(float))
        seconds.append(time.perf_counter() - t)
        preds.append([p[est.weights.param_names[i]] for i in order])
        t_err.append(1000 * float(np.linalg.norm(frame[:3, 3] - pose[:3, 3])))
        r_err.append(_rotation_deg(frame, pose))
    err = np.abs(np.array(preds) - params)
    lengths, angles = err[:, dims == "length"] * 1000, np.degrees(err[:, dims == "angle"])
    per_param = {
        n: round(float(e.mean() * (1000 if d == "length" else 180 / math.pi)), 2)
        for n, e, d in zip(names, err.T, dims, strict=True)
    }
    return {
        "views": len(points),
        "length_mae_mm": round(float(lengths.mean()), 2) if lengths.size else None,
        "angle_mae_deg": round(float(angles.mean()), 2) if angles.size else None,
        "within_5mm_pairs": round(float((lengths <= 5).mean()), 3) if lengths.size else None,
        "within_5mm_views": round(float((lengths <= 5).all(axis=1).mean()), 3)
        if lengths.size else None,
        "pose_origin_mm": round(float(np.median(t_err)), 1),
        "pose_rotation_deg": round(float(np.median(r_err)), 1),
        "ms_per_cloud": round(1000 * float(np.median(seconds)), 1),
        "per_param": per_param,
    }  # fmt: skip


def views_of(lib: Any, name: str, n: int, data: Path | None) -> tuple[Any, ...]:
    """(points, params, poses, names) of the held-out views of ``name``."""
    if data is not None:
        a = load_shards(data / name, name)
        return a.points[:n], a.params[:n], a.poses[:n], a.param_names
    views = generate_views(lib[name], n, HELD_OUT_SEED, points=1024, noise=0.002)
    names = tuple(views[0].params)
    return (np.stack([v.points for v in views]),
            np.array([[v.params[k] for k in names] for v in views]),
            np.stack([v.pose for v in views]), names)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--concepts", nargs="+", help="default: every concept with weights")
    parser.add_argument("--views", type=int, default=20, help="held-out views per concept (20)")
    parser.add_argument("--data", type=Path, help="held-out shards in DIR/CONCEPT/ instead")
    parser.add_argument("--out", type=Path, default=OUT, help="where the JSON goes")
    parser.add_argument("--small", action="store_true", help="four concepts, 8 views")
    parser.add_argument("--smoke", action="store_true", help="one concept, 3 views")
    args = parser.parse_args()
    torch.set_num_threads(1)
    names = args.concepts or list(shipped_concepts())
    if args.small:
        names, args.views = [n for n in SMALL if n in names], min(args.views, 8)
    if args.smoke:
        names, args.views = names[:1], 3
    lib = eac.load_library()
    t0 = time.perf_counter()
    rows = {}
    for name in names:
        rows[name] = evaluate(lib[name], *views_of(lib, name, args.views, args.data))
        print(name, json.dumps({k: v for k, v in rows[name].items() if k != "per_param"}))
    result = {
        "concepts": rows,
        "held_out_seed": HELD_OUT_SEED,
        "noise_sigma_m": 0.002,
        "seconds": round(time.perf_counter() - t0, 1),
        "machine": platform.processor() or platform.machine(),
        "torch": torch.__version__,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
