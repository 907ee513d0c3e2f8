"""Perception benchmark: concept parameters and pose from held-out synthetic views.

Run: ``.venv/bin/python bench/bench_perception.py [--n 6] [--seed 1000003] [--out FILE]
[--learned MODULE:FUNCTION] [--smoke | --small]`` (writes bench/results/perception.json and,
unless ``--smoke``, the plots docs/images/perception_errors.png and perception_<mode>.png).

Views come from ``grace_dsl.perception.views`` (depth noise sigma 2 mm, seeds disjoint from
training's, which uses small dataset seeds). Per concept and estimator: mean absolute error of the
length parameters (mm) and of the angle parameters (deg), the share of length estimates within
5 mm, the pose error (origin in mm, rotation in deg), the mean confidence and the median time per
part. Estimators:

- ``fit``: the analytic fit from its own global start (ICP from front views, joint states);
- ``near+fit``: the fit started near the truth (each parameter off by 5% of its range, 5 mm and
  2 deg of pose, the true joints): what a good learned start gives it, until weights exist;
- ``learned`` and ``learned+fit``: with ``--learned MODULE:FUNCTION``, a function
  ``(concept, points) -> Estimate`` (the learned estimator), alone and as the fit's start.

``--labels``: the same views (same instance, camera and noise), every pixel of the object with
the renderer's label per pixel (the shape it shows), fitted with ``estimate(..., labels=)``:
``fit`` (its own start), ``learned`` and ``learned+fit`` (labelled) where the concept has
shipped weights. The unlabelled rows of the same views are in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

import grace_dsl as eac  # noqa: E402
from grace_dsl.perception.estimate import estimate  # noqa: E402
from grace_dsl.perception.fit import fitted_instance_of  # noqa: E402
from grace_dsl.perception.types import Estimate, ViewSample  # noqa: E402
from grace_dsl.perception.views import generate_labelled_views, generate_views  # noqa: E402
from grace_dsl.perception.weights import shipped_concepts  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "bench" / "results" / "perception.json"
IMAGES = ROOT / "docs" / "images"
HANDLES = ["CurveHandle", "StraightHandle", "TBarHandle", "LeverHandle", "PocketHandle"]
OBJECTS = ["CabinetDrawer", "HingedCabinet", "DoorLeaf", "Microwave", "StoveKnob"]
TARGETS = {
    "length_mae_mm": 3.0,
    "angle_mae_deg": 3.0,
    "within_5mm": 0.95,
    "pose_mm": 5.0,
    "pose_deg": 3.0,
    "ms_per_part": 100.0,
}
HELDOUT_SEED = 1_000_003
FOLLOW = {"length": 0.3, "angle": 0.01}  # |d distance / d parameter| of a point that follows
MIN_MOVED = 5  # points
SURE_MM = 5.0  # a length whose reported spread (one sigma) is at most this counts as sure
EXAMPLE = "CabinetDrawer"  # the concept whose first view's fits are drawn


def dims(concept: eac.Concept) -> dict[str, str | None]:
    """The unit (``length``, ``angle``...) of each estimated parameter."""
    out: dict[str, str | None] = {}
    for s in concept.params:
        if s.kind == "num":
            out[s.name] = s.dim
        elif s.kind == "vec":
            out.update({f"{s.name}[{k}]": s.dim for k in range(s.size)})
    return out


def spans(concept: eac.Concept) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    for s in concept.params:
        if s.kind == "num":
            out[s.name] = (float(s.lo), float(s.hi))
        elif s.kind == "vec":
            out.update({f"{s.name}[{k}]": (float(s.lo[k]), float(s.hi[k])) for k in range(s.size)})
    return out


def near_start(concept: eac.Concept, view: ViewSample, rng: np.random.Generator) -> Estimate:
    """The truth, disturbed: 5% of each range, 5 mm and 2 deg of pose (a good learned start)."""
    params = {}
    for k, (lo, hi) in spans(concept).items():
        params[k] = float(np.clip(view.params[k] + rng.normal() * 0.05 * (hi - lo), lo, hi))
    axis = rng.normal(size=3)
    axis *= math.radians(2.0) / np.linalg.norm(axis)
    from grace_dsl.perception.fit import rotation_exp

    pose = view.pose.copy()
    pose[:3, :3] = pose[:3, :3] @ rotation_exp(axis)
    pose[:3, 3] += rng.normal(size=3) * 0.005 / math.sqrt(3)
    return Estimate(concept.name, params, pose, dict(view.joints), 0.0, 1.0, 0.0, "near")


def constrained(concept: eac.Concept, view: ViewSample) -> set[str]:
    """The parameters this view constrains: at least ``MIN_MOVED`` of the view's points, or of
    the free-space points within 10 mm of the true surface (the outline), follow the parameter
    (their distance changes by ``FOLLOW`` per unit of it: a third of a millimetre per
    millimetre, a centimetre per radian). The others no fit can read off this cloud: a
    drawer's travel (it only bounds the slide), a handle that got one or two of the 1024 points
    of a whole cabinet, the depth of a box behind its closed front."""
    from grace_dsl.perception.fit import Fitter, free_space
    from grace_dsl.perception.views import join_params

    fitter = Fitter(concept, join_params(concept, view.params, view.fixed), view.joints)
    frame = np.linalg.inv(view.pose)
    pts = view.points.astype(float)
    near = np.concatenate([pts, free_space(pts, np.zeros(3))])
    local = near @ frame[:3, :3].T + frame[:3, 3]
    d, g = fitter.model.gradient.batch(
        fitter.theta0, fitter._p(fitter.theta0), fitter.q0, np.zeros(6), local
    )
    d, g = np.asarray(d).reshape(-1), np.asarray(g).reshape(len(local), -1)
    keep = np.concatenate([np.ones(len(pts), bool), np.abs(d[len(pts) :]) < 0.01])
    out = set()
    units = dims(concept)
    for j, name in enumerate(spans(concept)):
        follow = FOLLOW.get(units[name] or "", FOLLOW["length"])
        if int((np.abs(g[keep, j]) >= follow).sum()) >= MIN_MOVED:
            out.add(name)
    return out


def errors(concept: eac.Concept, view: ViewSample, est: Estimate) -> dict[str, Any]:
    d = dims(concept)
    lengths = [abs(est.params[k] - view.params[k]) for k in view.params if d[k] == "length"]
    angles = [abs(est.params[k] - view.params[k]) for k in view.params if d[k] == "angle"]
    rel = est.pose[:3, :3].T @ view.pose[:3, :3]
    rot = math.degrees(math.acos(float(np.clip((np.trace(rel) - 1) / 2, -1, 1))))
    scale = {"length": 1000.0, "angle": 180 / math.pi}
    per = {k: scale.get(d[k] or "", 1.0) * abs(est.params[k] - view.params[k]) for k in view.params}
    seen = constrained(concept, view)
    sure = {k for k, v in est.spread.items() if d.get(k) == "length" and 1000 * v <= SURE_MM}
    return {
        # the lengths the estimator itself reports as sure (``Estimate.spread``)
        "sure_lengths_mm": [per[k] for k in view.params if k in sure],
        "per_param": per,
        "seen": sorted(seen),
        "seen_lengths_mm": [per[k] for k in view.params if d[k] == "length" and k in seen],
        "seen_angles_deg": [per[k] for k in view.params if d[k] == "angle" and k in seen],
        "lengths_mm": [1000 * x for x in lengths],
        "angles_deg": [math.degrees(x) for x in angles],
        "pose_mm": 1000 * float(np.linalg.norm(est.pose[:3, 3] - view.pose[:3, 3])),
        "pose_deg": rot,
        "ms": 1000 * est.seconds,
        "confidence": est.confidence,
    }


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    lengths = [x for r in rows for x in r["lengths_mm"]]
    angles = [x for r in rows for x in r["angles_deg"]]
    seen_l = [x for r in rows for x in r.get("seen_lengths_mm", [])]
    seen_a = [x for r in rows for x in r.get("seen_angles_deg", [])]
    sure_l = [x for r in rows for x in r.get("sure_lengths_mm", [])]
    return {
        "views": len(rows),
        # over the (view, parameter) pairs the view constrains (``constrained``)
        "seen_length_mae_mm": float(np.mean(seen_l)) if seen_l else None,
        "seen_angle_mae_deg": float(np.mean(seen_a)) if seen_a else None,
        "seen_within_5mm": float(np.mean(np.array(seen_l) <= 5.0)) if seen_l else None,
        "seen_share": len(seen_l) / max(len(lengths), 1),
        # over the lengths the estimate reports as sure (spread <= SURE_MM)
        "sure_within_5mm": float(np.mean(np.array(sure_l) <= 5.0)) if sure_l else None,
        "sure_length_mae_mm": float(np.mean(sure_l)) if sure_l else None,
        "sure_share": len(sure_l) / max(len(lengths), 1),
        "length_mae_mm": float(np.mean(lengths)) if lengths else None,
        "angle_mae_deg": float(np.mean(angles)) if angles else None,
        "within_5mm": float(np.mean(np.array(lengths) <= 5.0)) if lengths else None,
        "pose_mm": float(np.median([r["pose_mm"] for r in rows])),
        "pose_deg": float(np.median([r["pose_deg"] for r in rows])),
        "ms_per_part": float(np.median([r["ms"] for r in rows])),
        # CPU time of this process (``time.process_time``): what the machine's load does not
        # inflate, where it is measured (the labelled rows)
        "cpu_ms_per_part": float(np.median([r["cpu_ms"] for r in rows]))
        if rows and "cpu_ms" in rows[0]
        else None,
        "confidence": float(np.mean([r["confidence"] for r in rows])),
        # mm for lengths, deg for angles: which parameters a view does not show
        "per_param_mae": {
            k: float(np.mean([r["per_param"][k] for r in rows])) for k in rows[0]["per_param"]
        }
        if rows and "per_param" in rows[0]
        else {},
    }


def load_learned(spec: str | None) -> Any:
    """``MODULE:FUNCTION`` -> the function ``(concept, points) -> Estimate``, or None."""
    if not spec:
        return None
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def run_labelled(
    concept: eac.Concept, n: int, seed: int, learned: Any, modes: list[str]
) -> tuple[dict[str, list[dict[str, Any]]], dict[str, tuple[ViewSample, Estimate]]]:
    """The part-labelled rows: every pixel of each view with its shape label."""
    views = generate_labelled_views(concept, n, seed, noise=0.002, every_pixel=True)
    if learned is not None and not has_weights(concept.name):
        modes = [m for m in modes if "learned" not in m]
    rows: dict[str, list[dict[str, Any]]] = {m: [] for m in modes}
    example: dict[str, tuple[ViewSample, Estimate]] = {}
    estimate(concept, views[0][0].points, labels=views[0][1])  # warm-up, not timed
    for view, labels in views:
        pts = view.points.astype(float)
        for mode in modes:
            t0, c0 = time.perf_counter(), time.process_time()
            if mode == "fit":
                est = estimate(concept, pts, labels=labels)
            elif mode == "learned":
                est = learned(concept, pts)
            else:
                est = estimate(concept, pts, labels=labels, init=learned(concept, pts))
            cpu = time.process_time() - c0
            est = Estimate(**{**est.__dict__, "seconds": time.perf_counter() - t0})
            rows[mode].append(errors(concept, view, est) | {"cpu_ms": 1000 * cpu})
            example.setdefault(mode, (view, est))
    return rows, example


def has_weights(name: str) -> bool:
    """Whether the package ships the learned estimator's weights for ``name``."""
    return name in shipped_concepts()


def run_concept(
    concept: eac.Concept, n: int, seed: int, learned: Any, modes: list[str]
) -> tuple[dict[str, list[dict[str, Any]]], dict[str, tuple[ViewSample, Estimate]]]:
    views = generate_views(concept, n, seed, points=1024, noise=0.002)
    rng = np.random.default_rng(seed)
    rows: dict[str, list[dict[str, Any]]] = {m: [] for m in modes}
    example: dict[str, tuple[ViewSample, Estimate]] = {}
    # warm-up: the concept's compiled distance is built (and cached) once, not timed
    estimate(concept, views[0].points, init=near_start(concept, views[0], rng))
    for view in views:
        pts = view.points.astype(float)
        for mode in modes:
            if mode == "fit":
                est = estimate(concept, pts)
            elif mode == "near+fit":
                est = estimate(concept, pts, init=near_start(concept, view, rng))
            elif mode == "learned":
                est = learned(concept, pts)
            else:
                t0 = time.perf_counter()
                first = learned(concept, pts)
                est = estimate(concept, pts, init=first)
                est = Estimate(**{**est.__dict__, "seconds": time.perf_counter() - t0})
            rows[mode].append(errors(concept, view, est))
            example.setdefault(mode, (view, est))
    return rows, example


def histogram_png(values: dict[str, list[float]], path: Path, limit: float = 20.0) -> None:
    """Bars of |error| (mm) of the length parameters per estimator, 1 mm bins, PIL only."""
    from PIL import Image, ImageDraw

    width, height, pad = 720, 360, 40
    image = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(image)
    colours = [(200, 60, 60), (60, 110, 200), (60, 160, 90), (150, 90, 170)]
    bins = np.arange(0, limit + 1, 1.0)
    counts = {
        k: np.histogram(np.clip(v, 0, limit - 1e-9), bins)[0] / max(len(v), 1)
        for k, v in values.items()
    }
    top = max((c.max() for c in counts.values()), default=1) or 1
    slot = (width - 2 * pad) / len(bins[:-1])
    bar = slot / (len(counts) + 1)
    for j, (name, c) in enumerate(counts.items()):
        for i, share in enumerate(c):
            x0 = pad + i * slot + j * bar
            y0 = height - pad - (height - 2 * pad) * share / top
            draw.rectangle([x0, y0, x0 + bar - 1, height - pad], fill=colours[j % 4])
        draw.text((pad + 10, 10 + 14 * j), f"{name} (n={len(values[name])})", fill=colours[j % 4])
    draw.line([pad, height - pad, width - pad, height - pad], fill="black")
    for i in range(0, int(limit) + 1, 5):
        draw.text((pad + i * slot, height - pad + 5), f"{i} mm", fill="black")
    draw.text((width - 260, 10), "|length error|, last bin: >= 19 mm", fill="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, format="PNG", optimize=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=6, help="views per concept")
    ap.add_argument("--seed", type=int, default=HELDOUT_SEED)
    ap.add_argument("--out", type=Path, default=RESULT)
    ap.add_argument("--learned", metavar="MODULE:FUNCTION", help="the learned estimator")
    ap.add_argument("--concepts", help="comma-separated (default: 5 handles, 5 objects)")
    ap.add_argument("--smoke", action="store_true", help="1 concept, 1 view, no plots")
    ap.add_argument("--small", action="store_true", help="2 views per concept")
    ap.add_argument("--labels", action="store_true", help="the part-labelled fit")
    ap.add_argument("--log", type=Path, help="append each concept's summary as it finishes")
    args = ap.parse_args()
    lib = eac.load_library()
    names = args.concepts.split(",") if args.concepts else HANDLES + OBJECTS
    n = args.n
    if args.smoke:
        names, n = ["StraightHandle"], 1
    elif args.small:
        n = 2
    learned = load_learned(args.learned)
    modes = ["fit", "near+fit"] + (["learned", "learned+fit"] if learned else [])
    if args.labels:
        modes = ["fit"] + (["learned", "learned+fit"] if learned else [])
    start = time.perf_counter()
    table: dict[str, dict[str, Any]] = {}
    lengths: dict[str, list[float]] = {m: [] for m in modes}
    seen: dict[str, list[float]] = {m: [] for m in modes}
    sure: dict[str, list[float]] = {m: [] for m in modes}
    example: tuple[str, dict[str, tuple[ViewSample, Estimate]]] | None = None
    for name in names:
        run = run_labelled if args.labels else run_concept
        rows, ex = run(lib[name], n, args.seed, learned, modes)
        table[name] = {m: summary(r) for m, r in rows.items()}
        for m, r in rows.items():
            lengths[m] += [x for row in r for x in row["lengths_mm"]]
            seen[m] += [x for row in r for x in row["seen_lengths_mm"]]
            sure[m] += [x for row in r for x in row["sure_lengths_mm"]]
        if args.log:
            with args.log.open("a") as fh:
                fh.write(json.dumps({"concept": name, "summary": table[name]}) + "\n")
        if example is None or name == EXAMPLE:
            example = (name, ex)
        cells = "  ".join(
            f"{m}: {s['length_mae_mm'] or 0:.1f} mm (seen {s['seen_length_mae_mm'] or 0:.1f}) "
            f"{s['pose_mm']:.1f} mm/{s['pose_deg']:.1f} deg {s['ms_per_part']:.0f} ms"
            + (f" (cpu {s['cpu_ms_per_part']:.0f})" if s["cpu_ms_per_part"] is not None else "")
            for m, s in table[name].items()
        )
        print(f"{name:16s} {cells}", flush=True)
    overall = {
        m: summary(
            [
                {
                    "lengths_mm": lengths[m],
                    "angles_deg": [],
                    "pose_mm": 0,
                    "pose_deg": 0,
                    "ms": 0,
                    "confidence": 0,
                }
            ]
        )["within_5mm"]
        for m in modes
    }
    result = {
        "views_per_concept": n,
        "seed": args.seed,
        "noise_sigma_m": 0.002,
        "points": "every pixel, labelled" if args.labels else 1024,
        "modes": modes,
        "targets": TARGETS,
        "concepts": table,
        "within_5mm_all": overall,
        "within_5mm_seen": {
            m: float(np.mean(np.array(v) <= 5.0)) if v else None for m, v in seen.items()
        },
        "within_5mm_sure": {
            m: float(np.mean(np.array(v) <= 5.0)) if v else None for m, v in sure.items()
        },
        "sure_share": {m: len(sure[m]) / max(len(lengths[m]), 1) for m in modes},
        # the target is about what the view determines: the headline share is over the
        # length estimates each view constrains (``constrained``), with how many those are; the
        # rest (a closed drawer's travel, an absent handle kind's size) stay in the "all" share
        "headline": {
            m: {
                "within_5mm_seen": float(np.mean(np.array(seen[m]) <= 5.0)) if seen[m] else None,
                "seen_estimates": len(seen[m]),
                "all_estimates": len(lengths[m]),
                "within_5mm_all": overall[m],
            }
            for m in modes
        },
        "seconds": time.perf_counter() - start,
        "machine": f"{platform.machine()}, {os.cpu_count()} cpus, "
        f"python {platform.python_version()}",
        "command": " ".join(["bench/bench_perception.py", *sys.argv[1:]]),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"within 5 mm (all length parameters): {overall}; {result['seconds']:.0f} s")
    for m, h in result["headline"].items():
        print(
            f"headline {m}: {100 * (h['within_5mm_seen'] or 0):.1f} % within 5 mm of the "
            f"{h['seen_estimates']} length estimates the views constrain "
            f"({100 * (h['within_5mm_all'] or 0):.1f} % of all {h['all_estimates']})"
        )
    print(
        f"within 5 mm (the lengths reported sure): {result['within_5mm_sure']}, "
        f"share sure {result['sure_share']}"
    )
    if not args.smoke:
        tag = "perception_learned_errors" if learned else "perception_errors"
        tag = "perception_labelled_errors" if args.labels else tag
        histogram_png(lengths, IMAGES / f"{tag}.png")
        if example:
            from grace_dsl.perception.picture import fit_picture

            name, shots = example
            for mode, (view, est) in shots.items():
                inst = fitted_instance_of(lib[name], est)
                tag = ("labelled_" if args.labels else "") + mode.replace("+", "_")
                fit_picture(inst, view.points, IMAGES / f"perception_{tag}.png", size=360)
    return 0


if __name__ == "__main__":
    sys.exit(main())
