"""Runtime per call: instantiate a three-drawer chest, 16 grasps on a handle and one force, through
the public runtime API and through hand-written numpy written from the same ``.eac`` source.

    python bench/bench_runtime.py [--repeats 9] [--profile] [--out FILE] [--smoke]

The concept is the standard library's ``ChestOfDrawers`` (``concepts/cabinets.eac``): a carcass
with three drawers on prismatic runners, each with a ``StraightHandle`` part (three parts). One
call is what a perception stack does for each new estimate of the object:

    inst = chest.instantiate(pose=M, joints={"slide1": q1, "slide2": q2}, size=..., travel=...,
                             **{"handle1.length": ..., "handle1.radius": ...})
    G = inst.grasps("handle1.pull", n=16)       # (16, 4, 4)
    F = inst.force("open1", grasp=G[5])         # (3,)

The numpy rows compute the same from the source: the lets (``gap``, ``h``, ``t``, ``margin``),
the link pose ``M T(0, 0, q1)``, the part's placement ``T(0, gap + h, size.z / 2 + t +
standoff)``, the grasp family ``T(s, 0, 0) Ry(180deg)`` over 16 evenly spread ``s`` in
``[-length / 2 + margin, length / 2 - margin]``, and the force ``R (0, 0, 1)``:

* "simplified math": vectorised, with the products worked out by hand (one rotation for all
  grasps, positions as one broadcast) -- the fastest numpy we could write, with no checks;
* "as written": the source transcribed factor by factor, a 4x4 product chain per grasp, no checks;
* "validated": the simplified math after the checks the runtime makes (names, ranges, vector
  sizes, finiteness, the nine ``require``s, joint ranges, a rigid pose).

A fourth row calls the compiled native functions the runtime uses directly, without the API and
its checks: the floor of any runtime built on these three kernel calls. All must agree with
the runtime to 1e-9 before anything is timed.

The target (the issue: no slower than an equivalent hand-written numpy implementation) is the
"validated" row, which does what the runtime does, and the "as written" row; the script exits 1
if either is missed. The "simplified math" row skips every check and hand-folds the products for
this one concept: it is printed as a reference, the floor of what numpy can do here.

Each figure is the median (and min) over ``repeats`` interleaved timeit runs, each sized by
``Timer.autorange``. Results are printed and written to bench/results/runtime.json (``--out``).
``--smoke`` runs every case a few times (the test suite does, so a library change that breaks
the script fails CI); its timings mean nothing and its targets do not set the exit status.
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import json
import math
import os
import platform
import pstats
import statistics
import sys
import timeit
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

import grace_dsl as eac
from grace_dsl.compiler.resolve import stdlib_dir

RESULTS = Path(__file__).resolve().parent / "results" / "runtime.json"
N_GRASPS = 16
FORCE_AT = 5  # which of the 16 grasps the force is asked at

# ---------------------------------------------------------------- the workload


def world_pose() -> np.ndarray:
    """A rigid pose: rotated about z by 30 degrees and about x by 10, shifted."""
    cz, sz, cx, sx = math.cos(0.52), math.sin(0.52), math.cos(0.17), math.sin(0.17)
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    m = np.eye(4)
    m[:3, :3] = rz @ rx
    m[:3, 3] = (1.2, -0.4, 0.45)
    return m


POSE = world_pose()
JOINTS = {"slide1": 0.12, "slide2": 0.05}
PARAMS: dict[str, Any] = {
    "size": (0.9, 0.84, 0.5),
    "travel": 0.4,
    "handle1.length": 0.22,
    "handle1.radius": 0.007,
}


def runtime_call(chest: Any) -> tuple[np.ndarray, np.ndarray]:
    inst = chest.instantiate(pose=POSE, joints=JOINTS, **PARAMS)
    grasps = inst.grasps("handle1.pull", n=N_GRASPS)
    return grasps, inst.force("open1", grasp=grasps[FORCE_AT])


def kernels_only(chest: Any) -> Any:
    """The compiled functions the runtime calls, called directly: no API, no checks beyond the
    parameter packing. What the Python around them costs is the runtime's row minus this one."""
    checks, grasps_world, force_world = (chest.function(*k) for k in KERNELS)
    unit = np.linspace(0.0, 1.0, N_GRASPS).reshape(-1, 1)

    def call() -> tuple[np.ndarray, np.ndarray]:
        p = chest.pack(**PARAMS)
        checks(p)
        q = np.array([JOINTS["slide1"], JOINTS["slide2"], 0.0])
        grasps = grasps_world.batch(p, q, unit, POSE[:3])
        return grasps, force_world(p, q, POSE[:3], grasps[FORCE_AT, :3, 3]).reshape(3)

    return call


# the fused kernels of one step: requirements with joint ranges, the grasp family's poses in the
# world (its range inside), the world force (grace_dsl/compiler/functions.py)
KERNELS = (
    ("instance_checks",),
    ("grasps_world", "handle1.pull"),
    ("force", "open1"),
)

# ---------------------------------------------------------------- hand-written numpy

MM = 1e-3
# parameter: (lo, hi, default) in SI, from cabinets.eac and handles.eac
SCALARS = {
    "travel": (200 * MM, 550 * MM, 350 * MM),
    "handle1.length": (60 * MM, 600 * MM, 160 * MM),
    "handle1.radius": (4 * MM, 15 * MM, 6 * MM),
    "handle1.standoff": (20 * MM, 60 * MM, 32 * MM),
}
SIZE_LO, SIZE_HI = np.array([0.4, 0.5, 0.35]), np.array([1.2, 1.3, 0.6])
SIZE_DEFAULT = np.array([0.8, 0.78, 0.48])
GAP, T_FRONT = 20 * MM, 18 * MM
JOINT_NAMES = ("slide1", "slide2", "slide3")
RY_PI = np.array([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])  # Ry(180deg)
OPEN_LOCAL = np.array([0.0, 0.0, 1.0])  # slide1's axis, opening


def numpy_math(
    pose: np.ndarray, joints: Mapping[str, float], params: Mapping[str, Any]
) -> tuple[np.ndarray, np.ndarray]:
    """The chest's math as written in the source, without any checks."""
    size = np.asarray(params.get("size", SIZE_DEFAULT), dtype=float)
    length = float(params.get("handle1.length", SCALARS["handle1.length"][2]))
    radius = float(params.get("handle1.radius", SCALARS["handle1.radius"][2]))
    standoff = float(params.get("handle1.standoff", SCALARS["handle1.standoff"][2]))
    h = (size[1] - 4 * GAP) / 3
    margin = radius + 12 * MM
    # link drawer1 at q1, then the handle's placement: one translation, no rotation
    origin = np.array([0.0, GAP + h, joints.get("slide1", 0.0) + size[2] / 2 + T_FRONT + standoff])
    s = np.linspace(-length / 2 + margin, length / 2 - margin, N_GRASPS)
    rot = pose[:3, :3]
    grasps = np.zeros((N_GRASPS, 4, 4))
    grasps[:, :3, :3] = rot @ RY_PI
    grasps[:, :3, 3] = (origin + s[:, None] * np.array([1.0, 0.0, 0.0])) @ rot.T + pose[:3, 3]
    grasps[:, 3, 3] = 1.0
    return grasps, rot @ OPEN_LOCAL


def trans(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def roty(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s, 0.0], [0.0, 1.0, 0.0, 0.0], [-s, 0.0, c, 0.0], [0, 0, 0, 1.0]])


def numpy_as_written(
    pose: np.ndarray, joints: Mapping[str, float], params: Mapping[str, Any]
) -> tuple[np.ndarray, np.ndarray]:
    """The source transcribed factor by factor, one 4x4 product chain per grasp (no checks)."""
    size = params.get("size", SIZE_DEFAULT)
    length = params.get("handle1.length", SCALARS["handle1.length"][2])
    radius = params.get("handle1.radius", SCALARS["handle1.radius"][2])
    standoff = params.get("handle1.standoff", SCALARS["handle1.standoff"][2])
    gap, t = 20 * MM, 18 * MM
    h = (size[1] - 4 * gap) / 3
    margin = radius + 12 * MM
    link = trans(0, 0, joints.get("slide1", 0.0))  # prismatic slide1 along (0, 0, 1)
    handle = trans(0, gap + h, size[2] / 2 + t + standoff)  # part handle1 ... at trans(...)
    frame = pose @ link @ handle
    grasps = np.array(
        [
            frame @ trans(s, 0, 0) @ roty(math.pi)  # grasp pull(s) = trans(s, 0, 0) * roty(180deg)
            for s in np.linspace(-length / 2 + margin, length / 2 - margin, N_GRASPS)
        ]
    )
    return grasps, pose[:3, :3] @ np.array([0.0, 0.0, 1.0])


def numpy_validated(
    pose: Any, joints: Mapping[str, float], params: Mapping[str, Any]
) -> tuple[np.ndarray, np.ndarray]:
    """The same math after the checks the runtime makes (raising ValueError)."""
    m = np.asarray(pose, dtype=float)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ValueError("pose must be a finite 4x4 matrix")
    r = m[:3, :3]
    if np.abs(r.T @ r - np.eye(3)).max() > 1e-6 or np.abs(m[3] - (0, 0, 0, 1)).max() > 1e-12:
        raise ValueError("pose must be a rigid transform")
    values: dict[str, Any] = {}
    for name, value in params.items():
        if name == "size":
            v = np.asarray(value, dtype=float).reshape(-1)
            if v.size != 3 or not np.all(np.isfinite(v)):
                raise ValueError("size takes 3 finite values")
            if np.any(v < SIZE_LO - 1e-12) or np.any(v > SIZE_HI + 1e-12):
                raise ValueError("size is outside its range")
        elif name in SCALARS:
            v = float(value)
            lo, hi, _ = SCALARS[name]
            if not math.isfinite(v) or not lo - 1e-12 <= v <= hi + 1e-12:
                raise ValueError(f"{name} is outside its range")
        else:
            raise KeyError(name)
        values[name] = v
    size = values.get("size", SIZE_DEFAULT)
    travel, length, radius, standoff = (
        values.get(k, SCALARS[k][2])
        for k in ("travel", "handle1.length", "handle1.radius", "handle1.standoff")
    )
    h, margin = (size[1] - 4 * GAP) / 3, radius + 12 * MM
    requires = (
        standoff - radius >= 19 * MM,  # each handle (three alike): a finger behind the bar
        length / 2 > margin,  # each handle: the fingers fit between the posts
        travel <= size[2] - 50 * MM,
        length + 2 * radius < size[0] - 60 * MM,
        2 * radius < h - 20 * MM,
    )
    if not all(requires):
        raise ValueError("parameters violate a requirement")
    for name, q in joints.items():
        if name not in JOINT_NAMES:
            raise KeyError(name)
        if not math.isfinite(q) or not -1e-12 <= q <= travel + 1e-12:
            raise ValueError(f"joint {name} is outside its range")
    return numpy_math(m, joints, values)


# ---------------------------------------------------------------- measurement


def measure(
    calls: list[Callable[[], object]], repeats: int, number: int | None = None
) -> list[dict[str, float]]:
    """Median and min seconds per call of each callable over ``repeats`` interleaved runs (each
    sized by ``Timer.autorange``, or ``number`` calls)."""
    timers = [timeit.Timer(call) for call in calls]
    numbers = [number or timer.autorange()[0] for timer in timers]
    per_call: list[list[float]] = [[] for _ in calls]
    for _ in range(repeats):
        for timer, number, samples in zip(timers, numbers, per_call, strict=True):
            samples.append(timer.timeit(number) / number)
    return [
        {"median_s": statistics.median(p), "min_s": min(p), "number": n}
        for p, n in zip(per_call, numbers, strict=True)
    ]


def check_agreement(chest: Any) -> None:
    """Every variant agrees with the runtime (1e-9), and the runtime with its single grasps."""
    grasps, force = runtime_call(chest)
    variants = [
        functools.partial(v, POSE, JOINTS, PARAMS)
        for v in (numpy_math, numpy_as_written, numpy_validated)
    ]
    variants.append(kernels_only(chest))
    for variant in variants:
        g, f = variant()
        np.testing.assert_allclose(grasps, g, rtol=0, atol=1e-9)
        np.testing.assert_allclose(force, f, rtol=0, atol=1e-9)
    inst = chest.instantiate(pose=POSE, joints=JOINTS, **PARAMS)
    for g, s in zip(grasps, np.linspace(*inst.grasp_range("handle1.pull")["s"], N_GRASPS)):
        np.testing.assert_allclose(inst.grasp("handle1.pull", s=s), g, rtol=0, atol=1e-12)
    # the validated variant rejects what the runtime rejects
    for bad in ({"handle1.radius": 0.02}, {"handle1.standoff": 0.025}, {"travel": 0.5}):
        try:
            numpy_validated(POSE, JOINTS, {**PARAMS, **bad})
        except ValueError:
            pass
        else:
            raise AssertionError(f"the validated numpy variant accepted {bad}")
        try:
            chest.instantiate(pose=POSE, joints=JOINTS, **{**PARAMS, **bad})
        except eac.ParameterError:
            pass
        else:
            raise AssertionError(f"the runtime accepted {bad}")


def fmt(seconds: float) -> str:
    return f"{seconds * 1e6:,.1f} us"


def profile(chest: Any, calls: int = 3000, top: int = 25) -> None:
    prof = cProfile.Profile()
    prof.enable()
    for _ in range(calls):
        runtime_call(chest)
    prof.disable()
    pstats.Stats(prof).sort_stats("tottime").print_stats(top)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--profile", action="store_true", help="cProfile the runtime call")
    parser.add_argument("--out", type=Path, default=RESULTS, help="where the JSON goes")
    parser.add_argument("--smoke", action="store_true", help="a few calls: checks it runs")
    opts = parser.parse_args()
    if opts.smoke:
        opts.repeats = 1

    chest = eac.compile_paths([stdlib_dir() / "cabinets.eac"])["ChestOfDrawers"]
    check_agreement(chest)
    backend = chest.function("grasp", "handle1.pull").backend
    if opts.profile:
        profile(chest)
        return 0

    cases: list[tuple[str, Callable[[], object]]] = [
        ("numpy, simplified math (hand-written)", lambda: numpy_math(POSE, JOINTS, PARAMS)),
        ("numpy, as written (hand-written)", lambda: numpy_as_written(POSE, JOINTS, PARAMS)),
        ("numpy, validated (hand-written)", lambda: numpy_validated(POSE, JOINTS, PARAMS)),
        ("native kernels only (no API, no checks)", kernels_only(chest)),
        ("grace_dsl runtime", lambda: runtime_call(chest)),
    ]
    stats = measure([call for _, call in cases], opts.repeats, 20 if opts.smoke else None)
    rows = [{"case": name, **stat} for (name, _), stat in zip(cases, stats, strict=True)]
    runtime_s = rows[-1]["median_s"]
    for r in rows:
        r["runtime_over_this"] = runtime_s / r["median_s"]
    print(f"instantiate + {N_GRASPS} grasps + force, ChestOfDrawers (evaluator: {backend})")
    print(f"{'case':<40}{'median / call':>16}{'min / call':>14}{'runtime / this':>16}")
    for r in rows:
        print(
            f"{r['case']:<40}{fmt(r['median_s']):>16}{fmt(r['min_s']):>14}"
            f"{r['runtime_over_this']:>15.2f}x"
        )
    targets = {f"runtime <= {r['case']}": runtime_s <= r["median_s"] for r in rows[1:3]}
    for name, ok in targets.items():
        print(f"  [{'ok' if ok else 'MISSED'}] {name}")
    reference = rows[0]
    print(f"  [reference] runtime / {reference['case']}: {reference['runtime_over_this']:.2f}x")

    opts.out.parent.mkdir(parents=True, exist_ok=True)
    opts.out.write_text(
        json.dumps(
            {
                "command": "python bench/bench_runtime.py " + " ".join(sys.argv[1:]),
                "machine": {
                    "cores": len(os.sched_getaffinity(0)),
                    "python": platform.python_version(),
                    "numpy": np.__version__,
                    "load_average_1min_after": round(os.getloadavg()[0], 2),
                },
                "concept": "ChestOfDrawers",
                "evaluator": backend,
                "n_grasps": N_GRASPS,
                "repeats": opts.repeats,
                "rows": rows,
                "targets": targets,
            },
            indent=2,
        )
        + "\n"
    )
    print(f"wrote {opts.out}")
    return 0 if opts.smoke or all(targets.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
