"""``grace estimate CONCEPT cloud.ply|.npy``: fit a concept to a partial cloud; print and draw it.

The cloud is in the camera frame (metres; +z forward), as back-projected from a depth image;
``--png`` writes the fitted instance over the points. Bad input (an unknown concept, a file that
is not an (N, 3) cloud, too few points) is one line and exit code 1.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.cli.output import error, print_json, print_text
from grace_dsl.perception.errors import PointCloudError
from grace_dsl.runtime.errors import GraceError


def add_estimate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("concept", help="a concept of the standard library, e.g. CabinetDrawer")
    p.add_argument("cloud", help="the part's points: .npy (N, 3) or .ply, camera frame, metres")
    p.add_argument("--png", metavar="FILE", help="the fitted instance over the points")
    p.add_argument("--size", type=int, default=480, help="the picture's side in pixels (480)")
    p.add_argument("--seed", type=int, default=0, help="for subsampling and the search (0)")
    p.add_argument("--json", action="store_true", help="print the estimate as JSON")


def load_cloud(path: str | Path) -> np.ndarray:
    """An (N, 3) cloud from ``.npy`` or ``.ply``; ``PointCloudError`` otherwise."""
    path = Path(path)
    try:
        if path.suffix.lower() == ".npy":
            return np.asarray(np.load(path, allow_pickle=False), dtype=float)
        if path.suffix.lower() == ".ply":
            import trimesh

            loaded: Any = trimesh.load(path)  # a PointCloud or a mesh: both have vertices
            return np.asarray(loaded.vertices, float)
    except (OSError, ValueError, AttributeError) as exc:
        raise PointCloudError(f"{path}: cannot read a point cloud ({exc})") from None
    raise PointCloudError(f"{path}: give a .npy (N, 3) array or a .ply file")


def run_estimate(args: Any) -> int:
    """The body of ``grace estimate``; 0 on success, 1 with one line on stderr otherwise."""
    try:
        return _run(args)
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        return 1


def _run(args: Any) -> int:
    import grace_dsl as eac
    from grace_dsl.perception.estimate import estimate
    from grace_dsl.perception.fit import fitted_instance_of

    concept = eac.load_library()[args.concept]
    points = load_cloud(args.cloud)
    est = estimate(concept, points, seed=args.seed)
    if args.png:
        from grace_dsl.perception.picture import fit_picture

        fit_picture(fitted_instance_of(concept, est), points, args.png, size=args.size)
    if args.json:
        print_json(
            {
                "concept": est.concept,
                "params": est.params,
                "joints": est.joints,
                "pose": est.pose.tolist(),
                "residual_m": est.residual,
                "confidence": est.confidence,
                "seconds": est.seconds,
            }
        )
        return 0
    print_text(
        f"{est.concept}: residual {1000 * est.residual:.2f} mm, confidence "
        f"{est.confidence:.2f}, {1000 * est.seconds:.0f} ms"
    )
    for k, v in est.params.items():
        print_text(f"  {k} = {v:.4f}")
    for k, v in est.joints.items():
        print_text(f"  joint {k} = {v:.4f}")
    print_text(f"  position (camera frame) = {np.round(est.pose[:3, 3], 4).tolist()}")
    if args.png:
        print_text(f"picture: {args.png}")
    return 0
