"""Native evaluation of SX functions agrees with CasADi and falls back safely.

Tolerance: the native code is compiled with IEEE semantics (no -ffast-math), so it differs from
CasADi's VM only in the last bits: gcc contracts a*b+c into FMA and the vectorised batch loop
uses glibc's libmvec (<= 4 ulp).  An error of a few ulp *of the operands* can be large relative
to a result that cancels to ~0, so we compare with rtol = atol = 1e-12 on O(1) inputs, i.e.
1e-12 relative for O(1) values and 1e-12 absolute near zero.
"""

from __future__ import annotations

import ctypes
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grace_dsl.compiler import native

RTOL = ATOL = 1e-12


def close(got: object, ref: object) -> None:
    """Agreement to RTOL/ATOL; NaN must appear exactly where CasADi has NaN."""
    np.testing.assert_allclose(np.asarray(got), np.asarray(ref), rtol=RTOL, atol=ATOL)


x, y = ca.SX.sym("x"), ca.SX.sym("y")
v = ca.SX.sym("v", 3)
m = ca.SX.sym("m", 2, 3)
low = ca.SX.sym("low", ca.Sparsity.lower(3))  # sparse input


def _pos(e: ca.SX) -> ca.SX:
    return 1 + e * e


OP_FUNCTIONS: dict[str, ca.Function] = {
    "arith": ca.Function(
        "arith",
        [x, y],
        [
            ca.vertcat(
                x + y,
                x - y,
                x * y,
                x / _pos(y),
                -x,
                x**2,
                2 * x,
                1 / _pos(x),
                _pos(x) ** y,
                _pos(x) ** 3.5,
                ca.sqrt(_pos(x)),
                ca.exp(x),
                ca.log(_pos(y)),
            )
        ],
    ),
    "trig": ca.Function(
        "trig",
        [x, y],
        [
            ca.vertcat(
                ca.sin(x),
                ca.cos(y),
                ca.tan(x / 2),
                ca.asin(x / 4),
                ca.acos(y / 4),
                ca.atan(x),
                ca.atan2(x, y),
            )
        ],
    ),
    "misc": ca.Function(
        "misc",
        [x, y],
        [
            ca.vertcat(
                ca.fabs(x),
                ca.fmin(x, y),
                ca.fmax(x, y),
                ca.floor(x),
                ca.ceil(y),
                ca.sign(ca.floor(x)),
                ca.sinh(x),
                ca.cosh(y),
                ca.tanh(x),
                ca.asinh(y),
                ca.acosh(_pos(x)),
                ca.atanh(y / 4),
                ca.erf(x),
                ca.fmod(x, _pos(y)),
                ca.remainder(x, _pos(y)),
                ca.copysign(x, y),
                ca.hypot(x, y),
                ca.log1p(_pos(x)),
                ca.expm1(y),
            )
        ],
    ),
    "logic": ca.Function(
        "logic",
        [x, y],
        [
            ca.vertcat(
                ca.if_else(x < y, ca.sin(x), ca.cos(y)),
                x <= y,
                ca.floor(x) == ca.floor(y),
                ca.floor(x) != ca.floor(y),
                ca.logic_and(x > 0, y > 0),
                ca.logic_or(x > 0, y > 0),
                ca.logic_not(ca.floor(x)),
                ca.if_else(x >= 0, x, -2 * x, True),
            )
        ],
    ),
    # vector, matrix and sparse inputs; several outputs, one of them sparse with a constant
    "shapes": ca.Function(
        "shapes",
        [v, m, low, x],
        [ca.mtimes(m, v) * x, ca.diag(ca.sin(v)), ca.sum1(ca.sum2(low)) + 3.0, ca.mtimes(low, v).T],
    ),
}


def grasp() -> ca.Function:
    theta, r_out = ca.SX.sym("theta"), ca.SX.sym("r_out")
    c, s = ca.cos(theta), ca.sin(theta)
    rz = ca.SX.eye(4)
    rz[0, 0], rz[0, 1], rz[1, 0], rz[1, 1] = c, -s, s, c
    t = ca.SX.eye(4)
    t[1, 3] = -r_out
    rpy = np.array([[0, 0, 1, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=float)
    return ca.Function("pull_grasp", [theta, r_out], [rz @ t @ rpy])


FUNCTIONS = {**OP_FUNCTIONS, "pull_grasp": grasp()}


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("native_cache")


@pytest.fixture(scope="module")
def evaluators(cache: Path) -> dict[str, native.Evaluator]:
    if native.find_compiler() is None:
        pytest.skip("no C compiler")
    evs = native.fast_functions(FUNCTIONS, cache)
    assert {e.backend for e in evs.values()} == {"native"}
    return evs


def random_args(fn: ca.Function, rng: np.random.Generator, n: int | None = None) -> list:
    shapes = [(fn.size1_in(k), fn.size2_in(k)) for k in range(fn.n_in())]
    lead = () if n is None else (n,)
    return [rng.uniform(-2.0, 2.0, lead + shape) for shape in shapes]


def casadi_eval(fn: ca.Function, args: list) -> list[np.ndarray]:
    return [np.asarray(r.full()) for r in fn.call([ca.DM(a) for a in args])]


def as_tuple(out: native.Outputs) -> tuple[np.ndarray, ...]:
    return out if isinstance(out, tuple) else (out,)


def test_every_supported_op_is_exercised() -> None:
    used = {f.instruction_id(k) for f in OP_FUNCTIONS.values() for k in range(f.n_instructions())}
    supported = set(native._UNARY) | set(native._BINARY)
    supported |= {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST}
    missing = {native._OP_NAMES[op] for op in supported - used}
    assert not missing


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_single_matches_casadi(evaluators: dict, name: str) -> None:
    fn, ev = FUNCTIONS[name], evaluators[name]
    rng = np.random.default_rng(0)
    for _ in range(20):
        args = random_args(fn, rng)
        for got, ref in zip(as_tuple(ev(*args)), casadi_eval(fn, args), strict=True):
            assert got.shape == ref.shape
            close(got, ref)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.floats(-10, 10), st.floats(-10, 10))
def test_scalar_functions_match_casadi_property(evaluators: dict, a: float, b: float) -> None:
    for name in ("arith", "trig", "misc", "logic"):
        fn, ev = FUNCTIONS[name], evaluators[name]
        ref = casadi_eval(fn, [a, b])[0]
        close(ev(a, b), ref)
        close(ev.batch(np.array([a, a]), b)[1], ref)


def test_ieee_special_values_match_casadi(evaluators: dict) -> None:
    """No -ffast-math: NaN, inf and signed zeros behave exactly as in CasADi."""
    specials = [np.nan, np.inf, -np.inf, 0.0, -0.0, 1.0, -1.0]
    pairs = [(a, b) for a in specials for b in specials]
    for name in ("arith", "trig", "misc", "logic"):
        fn, ev = FUNCTIONS[name], evaluators[name]
        with np.errstate(all="ignore"):
            batch = ev.batch(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))
        for i, (a, b) in enumerate(pairs):
            ref = casadi_eval(fn, [a, b])[0]
            close(ev(a, b), ref)
            close(batch[i], ref)
    # atan2's branch cut depends on the sign of zero (-ffast-math would lose it)
    assert evaluators["trig"](-0.0, -1.0)[6, 0] == pytest.approx(-np.pi)


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
@pytest.mark.parametrize("n", [0, 1, 37, 5000])
def test_batch_matches_casadi_map(evaluators: dict, name: str, n: int) -> None:
    fn, ev = FUNCTIONS[name], evaluators[name]
    args = random_args(fn, np.random.default_rng(n), n)
    got = as_tuple(ev.batch(*args))
    ref = as_tuple(native.CasadiEvaluator(fn).batch(*args))
    for g, r, k in zip(got, ref, range(fn.n_out()), strict=True):
        assert g.shape == (n, fn.size1_out(k), fn.size2_out(k))
        close(g, r)
    if n:
        single = as_tuple(ev(*[a[n // 2] for a in args]))
        for g, s in zip(got, single, strict=True):
            close(g[n // 2], s)


def test_batch_threads_and_broadcasting(evaluators: dict) -> None:
    ev = evaluators["shapes"]
    rng = np.random.default_rng(1)
    n = 10_001  # > 2 chunks of 4096: every thread gets work, plus a ragged tail
    vs, ms, lows, xs = random_args(FUNCTIONS["shapes"], rng, n)
    full = as_tuple(ev.batch(vs, ms, lows, np.full(n, 0.5), threads=1))
    for threads in (2, 3):
        for a, b in zip(as_tuple(ev.batch(vs, ms, lows, 0.5, threads=threads)), full, strict=True):
            np.testing.assert_array_equal(a, b)
    # an unbatched matrix is broadcast; a column vector may be given as (N, 3) or (N, 3, 1)
    bcast = as_tuple(ev.batch(vs[:, :, 0], ms[0], lows, xs))
    expect = as_tuple(ev.batch(vs, np.broadcast_to(ms[0], ms.shape), lows, xs))
    for a, b in zip(bcast, expect, strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="batch sizes"):
        ev.batch(vs, ms[:5], lows, xs)
    with pytest.raises(ValueError, match="expects shape"):
        ev.batch(vs, ms[:, :1], lows, xs)
    with pytest.raises(TypeError):
        ev(1.0)


def test_single_call_is_thread_safe(evaluators: dict) -> None:
    ev, fn = evaluators["pull_grasp"], FUNCTIONS["pull_grasp"]
    thetas = np.linspace(-3, 3, 64)
    refs = [casadi_eval(fn, [t, 0.1])[0] for t in thetas]

    def work(i: int) -> bool:
        return all(
            np.allclose(np.asarray(ev(thetas[j], 0.1)), refs[j], rtol=RTOL, atol=ATOL)
            for j in range(i % 4, len(thetas), 4)
            for _ in range(20)
        )

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(work, range(8)))


def test_second_build_hits_the_cache(
    evaluators: dict, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    libs = list(cache.glob("*.so"))
    assert len(libs) == 1
    mtime = libs[0].stat().st_mtime_ns

    def no_build(*args: object, **kwargs: object) -> None:
        raise AssertionError("recompiled")

    monkeypatch.setattr(native, "build_shared_library", no_build)
    again = native.fast_functions(FUNCTIONS, cache)
    assert again["pull_grasp"].backend == "native"
    assert libs[0].stat().st_mtime_ns == mtime
    assert list(cache.glob("*.so")) == libs


def test_stale_library_is_rejected(evaluators: dict, cache: Path) -> None:
    path = next(cache.glob("*.so"))
    changed = ca.Function("pull_grasp", [x, y], [x * y])
    with pytest.raises(ValueError, match="stale"):
        native.load_native_library(path, {"pull_grasp": changed})


@pytest.mark.parametrize("disable", ["missing_cc", "flag"])
def test_fallback_without_compiler_gives_identical_results(
    disable: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    if disable == "missing_cc":
        monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    fn = FUNCTIONS["shapes"]
    ev = native.fast_function(fn, tmp_path, native=disable != "flag")
    assert ev.backend == "casadi"
    assert not list(tmp_path.glob("*.so"))
    rng = np.random.default_rng(2)
    args = random_args(fn, rng)
    for got, ref in zip(as_tuple(ev(*args)), casadi_eval(fn, args), strict=True):
        np.testing.assert_array_equal(got, ref)
    batch = random_args(fn, rng, 7)
    for k, got in enumerate(as_tuple(ev.batch(*batch))):
        for i in range(7):
            np.testing.assert_array_equal(got[i], casadi_eval(fn, [a[i] for a in batch])[k])


def test_unsupported_op_falls_back(evaluators: dict, cache: Path) -> None:
    bad = ca.Function("bad", [x], [ca.erfinv(x) + ca.sin(x)])
    with pytest.raises(native.NativeUnsupportedError, match="OP_ERFINV"):
        native.generate_c(bad, "bad")
    mixed = native.fast_functions({"bad": bad, "pull_grasp": FUNCTIONS["pull_grasp"]}, cache)
    assert mixed["bad"].backend == "casadi"
    assert mixed["pull_grasp"].backend == "native"
    close(mixed["bad"](0.3), casadi_eval(bad, [0.3])[0])


def test_mx_function_is_expanded(evaluators: dict, cache: Path) -> None:
    a = ca.MX.sym("a", 2)
    fn = ca.Function("mx", [a], [ca.sin(a) * ca.norm_2(a)])
    ev = native.fast_function(fn, cache)
    assert ev.backend == "native"
    close(ev([0.3, -0.4]), casadi_eval(fn, [[0.3, -0.4]])[0])


def test_concurrent_builds_leave_a_valid_library(tmp_path: Path) -> None:
    if native.find_compiler() is None:
        pytest.skip("no C compiler")
    source = native.generate_c(FUNCTIONS["trig"], "trig")
    results: list[Path | None] = []

    def build() -> None:
        results.append(native.build_shared_library(source, tmp_path, "same"))

    threads = [threading.Thread(target=build) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    path = tmp_path / "same.so"
    assert results == [path, path]
    assert [p.name for p in tmp_path.iterdir()] == ["same.so"]  # no temp files left behind
    ev = native.NativeFunction(
        FUNCTIONS["trig"], (ctypes.PyDLL(str(path)), ctypes.CDLL(str(path))), "trig"
    )
    close(ev(0.3, 0.2), casadi_eval(FUNCTIONS["trig"], [0.3, 0.2])[0])


def test_invalid_symbol_is_rejected() -> None:
    with pytest.raises(ValueError, match="identifier"):
        native.generate_c(FUNCTIONS["trig"], "not a symbol")
