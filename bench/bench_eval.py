"""Evaluation speed of the curved-handle pull grasp: hand-written numpy vs CasADi vs native C.

    python bench/bench_eval.py [--n 100000] [--repeats 7] [--out FILE] [--smoke]

G(theta, r_out) = Rz(theta) T(0, -r_out, 0) R_rpy(pi/2, 0, pi/2) Ry(pi/2), a 4x4 homogeneous
matrix: the paper's equation with its initial gripper pose G* = Ry(pi/2), exactly as the standard
library's ``CurveHandle.pull`` states it.  The CasADi and native rows evaluate the function the
compiler generates from ``concepts/handles.eac`` (inputs: the parameter vector p, laid out as the
concept's manifest says, with radian, r_in, r_out and height set and the rest at their defaults,
the empty joint vector q and the free parameter theta).
All variants run side by side in one process; each figure is the median over ``repeats``
interleaved timeit runs (each sized by ``Timer.autorange``) of the time per call.  Results are
printed and written to bench/results/eval.json (``--out``).  ``--smoke`` runs every case at a tiny
size (the test suite does, so a library change that breaks the script fails CI); its timings
mean nothing and its targets do not set the exit status.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from collections.abc import Callable
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

import grace_dsl as eac
from grace_dsl.compiler import native
from grace_dsl.compiler.build import front_end
from grace_dsl.compiler.functions import casadi_functions
from grace_dsl.compiler.resolve import stdlib_dir

RESULTS = Path(__file__).resolve().parent / "results" / "eval.json"


# ---------------------------------------------------------------- the grasp, three ways


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Homogeneous R_rpy(r, p, y) = Rz(y) Ry(p) Rx(r)."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    h = np.eye(4)
    h[:3, :3] = rz @ ry @ rx
    return h


G_STAR = rpy_matrix(0.0, math.pi / 2, 0.0)  # Ry(pi/2)
R_RPY = rpy_matrix(math.pi / 2, 0.0, math.pi / 2) @ G_STAR  # constant: precomputed once


def numpy_single(theta: float, r_out: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    rz = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)
    t = np.eye(4)
    t[1, 3] = -r_out
    return rz @ t @ R_RPY


def numpy_batch(theta: np.ndarray, r_out: np.ndarray) -> np.ndarray:
    n = theta.shape[0]
    c, s = np.cos(theta), np.sin(theta)
    rz = np.zeros((n, 4, 4))
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1] = c, -s, s, c
    rz[:, 2, 2] = rz[:, 3, 3] = 1.0
    t = np.tile(np.eye(4), (n, 1, 1))
    t[:, 1, 3] = -r_out
    return rz @ t @ R_RPY


def casadi_grasp() -> ca.Function:
    """The compiler's function for ``CurveHandle.pull``: G(p, q, theta)."""
    _, checked, diags = front_end([stdlib_dir()])
    assert not diags, diags
    return casadi_functions(checked, "CurveHandle").functions["grasp:pull"]


FIXED = {"radian": 2.0, "r_in": 0.015, "height": 0.012}  # what the benchmark keeps fixed
NO_JOINTS = np.zeros(0)


def curve_handle() -> eac.Concept:
    """The runtime's ``CurveHandle``: its manifest lays out the parameter vector."""
    return eac.compile_paths([stdlib_dir() / "handles.eac"])["CurveHandle"]


def params(concept: eac.Concept, r_out: float | np.ndarray) -> np.ndarray:
    """The parameter vector of ``concept`` (FIXED, r_out, defaults for the rest, in manifest
    order); one row per r_out when batched. Sizes and offsets come from the manifest, so a new
    parameter does not break the benchmark."""
    r = np.atleast_1d(np.asarray(r_out, dtype=float))
    base = concept.pack(**FIXED, r_out=float(r[0]))
    rows = np.tile(base, (len(r), 1))
    offset = next(s.offset for s in concept.params if s.name == "r_out")
    rows[:, offset] = r
    return rows[0] if np.ndim(r_out) == 0 else rows


# ---------------------------------------------------------------- measurement


def measure(
    calls: list[Callable[[], object]], repeats: int, number: int | None = None
) -> list[dict[str, float]]:
    """Median and min seconds per call of each callable over ``repeats`` timeit runs.

    Runs are sized by ``Timer.autorange`` (>= 0.2 s; ``number`` calls each when given) and
    interleaved round-robin, so background load on a shared machine hits all variants alike
    instead of skewing one of them.
    """
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


def machine() -> dict[str, str | int | float]:
    model = platform.processor()
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        model = (
            next(
                ln.split(":", 1)[1].strip()
                for ln in lscpu.splitlines()
                if ln.startswith("Model name")
            )
            or model
        )
    except (OSError, subprocess.SubprocessError, StopIteration):
        pass
    cc = native.find_compiler()
    return {
        "cpu": model,
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 0,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "casadi": str(getattr(ca, "__version__", "?")),
        "compiler": native._compiler_identity(tuple(cc)) if cc else "none",
    }


def fmt(seconds: float) -> str:
    return f"{seconds * 1e6:,.2f} us" if seconds < 1e-3 else f"{seconds * 1e3:,.2f} ms"


def print_table(rows: list[dict[str, Any]], title: str) -> None:
    header = ["case", "median / call", "min / call", "speed-up vs numpy", "vs CasADi"]
    cells = [
        [
            r["case"],
            fmt(r["median_s"]),
            fmt(r["min_s"]),
            f"{r['vs_numpy']:.1f}x",
            f"{r['vs_casadi']:.1f}x",
        ]
        for r in rows
    ]
    try:
        from rich.console import Console
        from rich.table import Table
    except ImportError:
        print(title)
        for line in [header, *cells]:
            print(f"{line[0]:<34}" + "".join(f"{c:>20}" for c in line[1:]))
        return
    table = Table(title=title)
    for i, h in enumerate(header):
        table.add_column(h, justify="left" if i == 0 else "right")
    for line in cells:
        table.add_row(*line)
    Console(width=max(120, Console().width)).print(table)


# ---------------------------------------------------------------- main


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000, help="batch size")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--out", type=Path, default=RESULTS, help="where the JSON goes")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: checks it runs")
    opts = parser.parse_args()
    if opts.smoke:
        opts.n, opts.repeats = 1000, 1

    fn = casadi_grasp()
    handle = curve_handle()
    assert fn.size1_in(0) == handle.entry["n_params"], "the manifest and the function disagree"
    with tempfile.TemporaryDirectory() as cold:
        start = time.perf_counter()
        native.fast_function(fn, Path(cold))
        cold_build_s = time.perf_counter() - start
    ev = native.fast_function(fn)  # default cache: compiled at most once per machine
    if ev.backend != "native":
        print("warning: no working C compiler; 'native' rows measure the CasADi fallback")
    fmap = fn.map(opts.n, "thread", 2)
    fmap_serial = fn.map(opts.n, "serial")

    rng = np.random.default_rng(0)
    theta0, r0 = 0.7, 0.04
    thetas = rng.uniform(-math.pi, math.pi, opts.n)
    radii = rng.uniform(0.02, 0.08, opts.n)

    p0, pn, qn = params(handle, r0), params(handle, radii), np.zeros((0, opts.n))
    pt, tt = pn.T.copy(), thetas[None, :].copy()  # CasADi's map takes one column per sample

    # agreement before timing
    ref_single = numpy_single(theta0, r0)
    np.testing.assert_allclose(ev(p0, NO_JOINTS, theta0), ref_single, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(fn(p0, NO_JOINTS, theta0).full(), ref_single, rtol=1e-12, atol=1e-12)
    ref_batch = numpy_batch(thetas, radii)
    np.testing.assert_allclose(ev.batch(pn, NO_JOINTS, thetas), ref_batch, rtol=1e-12, atol=1e-12)
    mapped = fmap(pt, qn, tt).full()
    np.testing.assert_allclose(
        mapped.reshape(4, opts.n, 4).transpose(1, 0, 2), ref_batch, rtol=1e-12, atol=1e-12
    )

    cases: list[tuple[str, str, Callable[[], object]]] = [
        ("single", "numpy (hand-written)", lambda: numpy_single(theta0, r0)),
        ("single", "CasADi Function call", lambda: fn(p0, NO_JOINTS, theta0)),
        ("single", "native", lambda: ev(p0, NO_JOINTS, theta0)),
        ("batch", f"numpy vectorised, N={opts.n:,}", lambda: numpy_batch(thetas, radii)),
        ("batch", f"CasADi map thread x2, N={opts.n:,}", lambda: fmap(pt, qn, tt)),
        ("batch", f"CasADi map serial, N={opts.n:,}", lambda: fmap_serial(pt, qn, tt)),
        (
            "batch",
            f"native, 1 thread, N={opts.n:,}",
            lambda: ev.batch(pn, NO_JOINTS, thetas, threads=1),
        ),
        ("batch", f"native, N={opts.n:,}", lambda: ev.batch(pn, NO_JOINTS, thetas)),
    ]
    stats = measure([call for _, _, call in cases], opts.repeats, 3 if opts.smoke else None)
    rows: list[dict[str, Any]] = [
        {"kind": kind, "case": name, **stat}
        for (kind, name, _), stat in zip(cases, stats, strict=True)
    ]
    for kind in ("single", "batch"):
        group = [r for r in rows if r["kind"] == kind]
        numpy_s, casadi_s = group[0]["median_s"], group[1]["median_s"]
        for r in group:
            r["vs_numpy"], r["vs_casadi"] = numpy_s / r["median_s"], casadi_s / r["median_s"]

    by = {
        (r["kind"], i): r
        for kind in ("single", "batch")
        for i, r in enumerate(x for x in rows if x["kind"] == kind)
    }
    native_single, native_batch = by[("single", 2)]["median_s"], rows[-1]["median_s"]
    targets = {
        "native single <= numpy single": native_single <= by[("single", 0)]["median_s"],
        "native single <= 0.5 x CasADi call": native_single <= 0.5 * by[("single", 1)]["median_s"],
        "native batch <= 0.1 x numpy batch": native_batch <= 0.1 * by[("batch", 0)]["median_s"],
    }

    info = machine()
    info["load_average_1min_after"] = round(os.getloadavg()[0], 2)  # background load during run
    print_table(rows, f"pull grasp evaluation on {info['cpu']} ({info['cores']} cores)")
    print(
        f"native backend: {ev.backend}; cold compile + load {cold_build_s * 1e3:.0f} ms "
        f"(cached afterwards); flags {' '.join(native.FLAG_TIERS[0])}"
    )
    for name, ok in targets.items():
        print(f"  [{'ok' if ok else 'MISSED'}] {name}")

    opts.out.parent.mkdir(parents=True, exist_ok=True)
    opts.out.write_text(
        json.dumps(
            {
                "command": "python bench/bench_eval.py " + " ".join(sys.argv[1:]),
                "machine": info,
                "batch_n": opts.n,
                "repeats": opts.repeats,
                "native_backend": ev.backend,
                "cold_build_s": cold_build_s,
                "flags": list(native.FLAG_TIERS[0]),
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
