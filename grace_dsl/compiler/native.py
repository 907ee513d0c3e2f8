"""Native evaluation of CasADi SX functions: emit C from the expression graph, compile once, call.

Why: the runtime evaluates concept functions (grasp poses, constraints) in tight loops.  CasADi's
Python call costs ~25 us and its ``map`` ~0.5 us per sample, which is no faster than hand-written
numpy.  A straight-line C kernel generated from the SX algorithm costs ~1 us per call from Python
(dominated by ctypes) and a few ns per sample in a vectorised batch loop.

Design:

* :func:`generate_c` walks the SX instruction list and emits two entry points per function,
  ``<sym>_one`` (one sample, dense column-major inputs/outputs concatenated) and ``<sym>_batch``
  (struct-of-arrays per argument, a loop gcc vectorises, optionally split over pthreads).
* Ops the generator does not know raise :class:`NativeUnsupportedError`, never wrong code.
* :func:`build_shared_library` compiles with the system C compiler, atomically; it returns
  ``None`` when there is no compiler or compilation fails, and callers fall back to CasADi.
* :func:`fast_function` / :func:`fast_functions` return the best evaluator available with one
  interface (``__call__`` for one sample, ``batch`` for many) and cache the ``.so`` by content hash.

Floating point: we do *not* use ``-ffast-math``; it assumes finite values, reassociates and drops
signed zeros, which changes NaN/Inf propagation, ``if_else``, ``fmin``/``fmax`` and atan2's branch
cut.  We only drop errno and trap semantics and ask glibc for its libmvec SIMD declarations (see
``_PRELUDE``), so loops over sin/cos/exp/... still vectorise.  Results then differ from CasADi only
in the last bits (FMA contraction, libmvec's <= 4 ulp transcendental functions).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import hashlib
import logging
import os
import platform
import re
import shlex
import shutil
import signal
import subprocess
import tempfile
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Protocol, cast

import casadi
import numpy as np
import numpy.typing as npt

from grace_dsl.cache import cache_dir, untrusted_reason
from grace_dsl.errors import GraceError

__all__ = [
    "CasadiEvaluator",
    "Evaluator",
    "NativeFunction",
    "NativeUnsupportedError",
    "build_native_library",
    "build_shared_library",
    "file_sha256",
    "load_unit_library",
    "toolchain_fingerprint",
    "default_cache_dir",
    "fast_function",
    "fast_functions",
    "find_compiler",
    "generate_c",
    "generate_library_c",
    "load_native_library",
    "symbol_for",
]

logger = logging.getLogger(__name__)

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
Outputs = FloatArray | tuple[FloatArray, ...]

#: Bumped whenever the generated code or the calling convention changes (invalidates caches).
ABI_VERSION = 1
#: Samples per thread below which ``batch`` stays single-threaded (thread start ~20-50 us).
MIN_SAMPLES_PER_THREAD = 16384
#: Upper bound on threads chosen automatically by ``batch``.
MAX_AUTO_THREADS = 8
#: IEEE-preserving optimisation flags.  sin/cos must not be builtins: gcc would merge sin(x) and
#: cos(x) into one complex sincos call, which blocks vectorisation of the whole loop.
_OPT_FLAGS = (
    "-O3",
    "-fno-math-errno",
    "-fno-trapping-math",
    "-fno-builtin-sin",
    "-fno-builtin-cos",
)
#: Compiler flag tiers, tried in order: tuned for this CPU, then portable.
FLAG_TIERS: tuple[tuple[str, ...], ...] = (("-march=native", *_OPT_FLAGS), _OPT_FLAGS)
_LINK_FLAGS = ("-shared", "-fPIC", "-pthread")
_COMPILE_TIMEOUT_S = 600.0
_NONE: frozenset[int] = frozenset()  # no uniform inputs (``fast_functions``)


class NativeUnsupportedError(GraceError, ValueError):
    """A function cannot be lowered to C (unknown op, free variables, non-SX); use CasADi."""


# --------------------------------------------------------------------------------------------
# Function layout (shapes, offsets) shared by the native and the CasADi evaluators
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Arg:
    """One input or output: its dense shape and its offset in the concatenated dense vector."""

    name: str
    rows: int
    cols: int
    offset: int

    @functools.cached_property
    def size(self) -> int:
        return self.rows * self.cols

    @functools.cached_property
    def sample_shapes(self) -> tuple[tuple[int, ...], ...]:
        """Shapes accepted for one sample: (r, c), plus (r,) for vectors and () for scalars."""
        shapes: list[tuple[int, ...]] = [(self.rows, self.cols)]
        if self.rows == 1 or self.cols == 1:
            shapes.append((self.size,))
        if self.size == 1:
            shapes.append(())
        return tuple(shapes)


@dataclass(frozen=True)
class _Layout:
    """Dense shapes of a function's inputs and outputs."""

    name: str
    inputs: tuple[_Arg, ...]
    outputs: tuple[_Arg, ...]

    @staticmethod
    def of(fn: casadi.Function) -> _Layout:
        def args(
            n: int, sparsity: Callable[[int], Any], name: Callable[[int], str]
        ) -> tuple[_Arg, ...]:
            out, offset = [], 0
            for k in range(n):
                sp = sparsity(k)
                out.append(_Arg(name(k), sp.size1(), sp.size2(), offset))
                offset += sp.size1() * sp.size2()
            return tuple(out)

        return _Layout(
            fn.name(),
            args(fn.n_in(), fn.sparsity_in, fn.name_in),
            args(fn.n_out(), fn.sparsity_out, fn.name_out),
        )

    @property
    def n_in(self) -> int:
        return sum(a.size for a in self.inputs)

    @property
    def n_out(self) -> int:
        return sum(a.size for a in self.outputs)

    def check_arity(self, args: Sequence[object]) -> None:
        if len(args) != len(self.inputs):
            raise TypeError(f"{self.name} takes {len(self.inputs)} arguments, got {len(args)}")

    def sample(self, k: int, value: ArrayLike) -> FloatArray:
        """One unbatched argument as an (r, c) float array."""
        arg = self.inputs[k]
        arr = value if type(value) is np.ndarray else np.asarray(value, dtype=np.float64)
        if arr.shape not in arg.sample_shapes:
            raise ValueError(
                f"{self.name}: input {arg.name!r} expects shape "
                f"{(arg.rows, arg.cols)}, got {arr.shape}"
            )
        return arr.reshape(arg.rows, arg.cols)

    def split_batch(self, args: Sequence[ArrayLike]) -> tuple[int, list[tuple[FloatArray, bool]]]:
        """Classify batch arguments: N and, per input, ((N, r, c) array, True) or ((r, c), False).

        An argument whose shape is a valid single-sample shape is broadcast; otherwise its leading
        axis is the batch axis.  All batched arguments must agree on N (N = 1 if none is batched).
        """
        self.check_arity(args)
        split: list[tuple[FloatArray, bool]] = []
        n: int | None = None
        for arg, value in zip(self.inputs, args, strict=True):
            arr = np.asarray(value, dtype=np.float64)
            if arr.shape in arg.sample_shapes:
                split.append((arr.reshape(arg.rows, arg.cols), False))
                continue
            if arr.ndim == 0 or arr.shape[1:] not in arg.sample_shapes:
                raise ValueError(
                    f"{self.name}: input {arg.name!r} expects shape "
                    f"(N, {arg.rows}, {arg.cols}) or {(arg.rows, arg.cols)}, "
                    f"got {arr.shape}"
                )
            if n is not None and arr.shape[0] != n:
                raise ValueError(f"{self.name}: batch sizes disagree ({n} vs {arr.shape[0]})")
            n = arr.shape[0]
            split.append((arr.reshape(n, arg.rows, arg.cols), True))
        return (1 if n is None else n), split


def _pack(outs: list[FloatArray]) -> Outputs:
    """Mirror CasADi's Python convention: one output -> array, several -> tuple."""
    return outs[0] if len(outs) == 1 else tuple(outs)


# --------------------------------------------------------------------------------------------
# C generation
# --------------------------------------------------------------------------------------------

_PRELUDE = r"""/* Generated by grace_dsl.compiler.native -- do not edit. */
#include <limits.h> /* pulls in <features.h>, which defines __GLIBC__ */
#if defined(__GLIBC__) && !defined(__FAST_MATH__)
/* glibc declares the SIMD (libmvec) variants of sin, cos, exp, ... only under __FAST_MATH__.
   We want vectorised loops without -ffast-math's IEEE-breaking assumptions, so we request the
   declarations alone; the code is still compiled with IEEE semantics. */
#define __FAST_MATH__ 1
#define GRACE_UNDEF_FAST_MATH 1
#endif
#include <math.h>
#ifdef GRACE_UNDEF_FAST_MATH
#undef __FAST_MATH__
#endif
#include <pthread.h>

#if defined(__clang__)
#define GRACE_IVDEP _Pragma("clang loop vectorize(assume_safety)")
#elif defined(__GNUC__)
#define GRACE_IVDEP _Pragma("GCC ivdep")
#else
#define GRACE_IVDEP
#endif

typedef void (*grace_range_fn)(long, long, long, const double* const*, double* const*);
typedef struct {
  grace_range_fn f; long n, chunk; long* next; const double* const* in; double* const* out;
} grace_job;

/* Threads grab chunks from a shared counter, so a thread that is descheduled (shared
   machine) delays the call by at most one chunk instead of by its whole share. */
static void* grace_run(void* p) {
  grace_job* j = (grace_job*)p;
  for (;;) {
    long i0 = __atomic_fetch_add(j->next, j->chunk, __ATOMIC_RELAXED);
    if (i0 >= j->n) return 0;
    j->f(j->n, i0, i0 + j->chunk < j->n ? i0 + j->chunk : j->n, j->in, j->out);
  }
}

/* Evaluate samples [0, n) on nthreads threads (the caller is one of them); fork-safe because
   no thread outlives the call.  If pthread_create fails, the remaining threads do the work. */
static void grace_parallel(grace_range_fn f, long n, const double* const* in,
                           double* const* out, int nthreads) {
  enum { MAXT = 64, CHUNK = 4096 };
  pthread_t th[MAXT]; int started[MAXT];
  long next = 0;
  grace_job job = {f, n, CHUNK, &next, in, out};
  if (nthreads > MAXT) nthreads = MAXT;
  if (nthreads <= 1 || n <= CHUNK) { f(n, 0, n, in, out); return; }
  for (int t = 1; t < nthreads; ++t) started[t] = pthread_create(&th[t], 0, grace_run, &job) == 0;
  grace_run(&job);
  for (int t = 1; t < nthreads; ++t) if (started[t]) pthread_join(th[t], 0);
}
"""

_UNARY: dict[int, str] = {
    casadi.OP_NEG: "-{0}",
    casadi.OP_SQ: "{0} * {0}",
    casadi.OP_TWICE: "2.0 * {0}",
    casadi.OP_INV: "1.0 / {0}",
    casadi.OP_SQRT: "sqrt({0})",
    casadi.OP_EXP: "exp({0})",
    casadi.OP_LOG: "log({0})",
    casadi.OP_EXPM1: "expm1({0})",
    casadi.OP_LOG1P: "log1p({0})",
    casadi.OP_SIN: "sin({0})",
    casadi.OP_COS: "cos({0})",
    casadi.OP_TAN: "tan({0})",
    casadi.OP_ASIN: "asin({0})",
    casadi.OP_ACOS: "acos({0})",
    casadi.OP_ATAN: "atan({0})",
    casadi.OP_SINH: "sinh({0})",
    casadi.OP_COSH: "cosh({0})",
    casadi.OP_TANH: "tanh({0})",
    casadi.OP_ASINH: "asinh({0})",
    casadi.OP_ACOSH: "acosh({0})",
    casadi.OP_ATANH: "atanh({0})",
    casadi.OP_ERF: "erf({0})",
    casadi.OP_FABS: "fabs({0})",
    casadi.OP_FLOOR: "floor({0})",
    casadi.OP_CEIL: "ceil({0})",
    # CasADi: sign(0) = 0 and sign(NaN) = NaN, hence the trailing {0}.
    casadi.OP_SIGN: "{0} < 0 ? -1.0 : ({0} > 0 ? 1.0 : {0})",
    casadi.OP_NOT: "!{0}",
}

_BINARY: dict[int, str] = {
    casadi.OP_ADD: "{0} + {1}",
    casadi.OP_SUB: "{0} - {1}",
    casadi.OP_MUL: "{0} * {1}",
    casadi.OP_DIV: "{0} / {1}",
    casadi.OP_POW: "pow({0}, {1})",
    casadi.OP_CONSTPOW: "pow({0}, {1})",
    casadi.OP_ATAN2: "atan2({0}, {1})",
    casadi.OP_HYPOT: "hypot({0}, {1})",
    casadi.OP_FMIN: "fmin({0}, {1})",
    casadi.OP_FMAX: "fmax({0}, {1})",
    casadi.OP_FMOD: "fmod({0}, {1})",
    casadi.OP_REMAINDER: "remainder({0}, {1})",
    casadi.OP_COPYSIGN: "copysign({0}, {1})",
    casadi.OP_LT: "{0} < {1}",
    casadi.OP_LE: "{0} <= {1}",
    casadi.OP_EQ: "{0} == {1}",
    casadi.OP_NE: "{0} != {1}",
    casadi.OP_AND: "{0} && {1}",
    casadi.OP_OR: "{0} || {1}",
    # CasADi: if_else_zero(c, x) = c == 0 ? 0 : x  (if_else(c, a, b) lowers to two of these).
    casadi.OP_IF_ELSE_ZERO: "{0} != 0 ? {1} : 0.0",
}

_OP_NAMES = {getattr(casadi, n): n for n in dir(casadi) if n.startswith("OP_")}
_SYMBOL_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def _c_double(value: float) -> str:
    """Exact C literal for a double (hex float), including inf/nan."""
    if np.isnan(value):
        return "NAN"
    if np.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    return f"({float(value).hex()})"


@dataclass(frozen=True)
class _Kernel:
    """An SX algorithm lowered to straight-line C, independent of the memory layout.

    ``loads`` are (variable, input index, dense element); ``stores`` are (output index, dense
    element, variable or literal).  Loads come first and stores last so the body is pure
    register computation, which keeps gcc's vectoriser free of aliasing doubts.
    """

    layout: _Layout
    n_work: int
    loads: tuple[tuple[str, int, int], ...]
    body: tuple[str, ...]
    stores: tuple[tuple[int, int, str], ...]


def _as_sx(fn: casadi.Function) -> casadi.Function:
    if not fn.is_a("SXFunction"):
        try:
            fn = fn.expand()
        except RuntimeError as err:
            raise NativeUnsupportedError(f"{fn.name()}: cannot expand to SX: {err}") from err
    if fn.has_free():
        raise NativeUnsupportedError(f"{fn.name()}: free variables {fn.get_free()}")
    return fn


def _lower(fn: casadi.Function) -> _Kernel:
    """Translate the SX instruction list of ``fn`` into C statements (see :class:`_Kernel`)."""
    fn = _as_sx(fn)
    layout = _Layout.of(fn)
    in_dense = [fn.sparsity_in(k).find() for k in range(fn.n_in())]
    out_dense = [fn.sparsity_out(k).find() for k in range(fn.n_out())]
    loads: dict[tuple[int, int], str] = {}
    body: list[str] = []
    results: dict[tuple[int, int], str] = {}
    n_work = 0
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        arg = fn.instruction_input(k)
        res = fn.instruction_output(k)
        if op == casadi.OP_OUTPUT:
            key = (res[0], out_dense[res[0]][res[1]])
            results[key] = f"y{key[0]}_{key[1]}"
            body.append(f"{results[key]} = w{arg[0]};")
            continue
        n_work = max(n_work, res[0] + 1)
        if op == casadi.OP_INPUT:
            key = (arg[0], in_dense[arg[0]][arg[1]])
            var = loads.setdefault(key, f"x{key[0]}_{key[1]}")
            expr = var
        elif op == casadi.OP_CONST:
            expr = _c_double(fn.instruction_constant(k))
        elif op in _UNARY:
            expr = _UNARY[op].format(f"w{arg[0]}")
        elif op in _BINARY:
            expr = _BINARY[op].format(f"w{arg[0]}", f"w{arg[1]}")
        else:
            name = _OP_NAMES.get(op, str(op))
            raise NativeUnsupportedError(f"{fn.name()}: operation {name} is not supported")
        body.append(f"w{res[0]} = {expr};")
    stores = [
        (o, j, results.get((o, j), "0.0"))
        for o, arg_o in enumerate(layout.outputs)
        for j in range(arg_o.size)
    ]
    load_list = tuple((v, key[0], key[1]) for key, v in loads.items())
    return _Kernel(layout, n_work, load_list, tuple(body), tuple(stores))


def _declarations(kernel: _Kernel, indent: str) -> list[str]:
    names = [f"w{i}" for i in range(kernel.n_work)]
    names += [var for _, _, var in kernel.stores if var != "0.0"]
    return [f"{indent}double {', '.join(names[i : i + 16])};" for i in range(0, len(names), 16)]


def _render_one(kernel: _Kernel, symbol: str) -> list[str]:
    offs_in = [a.offset for a in kernel.layout.inputs]
    offs_out = [a.offset for a in kernel.layout.outputs]
    lines = [f"void {symbol}_one(const double* restrict in, double* restrict out) {{"]
    lines += [f"  const double {v} = in[{offs_in[k] + j}];" for v, k, j in kernel.loads]
    lines += _declarations(kernel, "  ")
    lines += [f"  {s}" for s in kernel.body]
    lines += [f"  out[{offs_out[o] + j}] = {v};" for o, j, v in kernel.stores]
    return [*lines, "}"]


def _render_batch(kernel: _Kernel, symbol: str, uniform: frozenset[int] = frozenset()) -> list[str]:
    """The batch loop; inputs in ``uniform`` are one value for every sample (``in[k]`` holds
    one sample's elements), loaded once before the loop instead of per sample."""
    ins = range(len(kernel.layout.inputs))
    outs = range(len(kernel.layout.outputs))
    lines = [
        f"static void {symbol}_range(long n, long i0, long i1, const double* const* in, "
        "double* const* out) {",
        *(f"  const double* restrict a{k} = in[{k}];" for k in ins),
        *(f"  double* restrict r{k} = out[{k}];" for k in outs),
        *(f"  const double {v} = a{k}[{j}];" for v, k, j in kernel.loads if k in uniform),
        "  (void)n;",
        "  GRACE_IVDEP",
        "  for (long i = i0; i < i1; ++i) {",
        *(
            f"    const double {v} = a{k}[{j}L * n + i];"
            for v, k, j in kernel.loads
            if k not in uniform
        ),
        *_declarations(kernel, "    "),
        *(f"    {s}" for s in kernel.body),
        *(f"    r{o}[{j}L * n + i] = {v};" for o, j, v in kernel.stores),
        "  }",
        "}",
        f"void {symbol}_batch(long n, const double* const* in, double* const* out, "
        "int nthreads) {",
        f"  grace_parallel({symbol}_range, n, in, out, nthreads);",
        "}",
    ]
    return lines


def _check_symbol(symbol: str) -> None:
    if not _SYMBOL_RE.match(symbol):
        raise ValueError(f"not a valid C identifier: {symbol!r}")


@dataclass(frozen=True)
class _Generated:
    """C for one function (without prelude) and the digest embedded in it."""

    symbol: str
    code: str
    digest: str


def _function_c(
    fn: casadi.Function, symbol: str, uniform: frozenset[int] = frozenset()
) -> _Generated:
    """C for one function; it exports ``<symbol>_digest`` (of prelude, ABI version and body)
    so a stale library is detected at load time. ``uniform``: see :func:`fast_functions`."""
    _check_symbol(symbol)
    kernel = _lower(fn)
    batch = _render_batch(kernel, symbol, uniform)
    code = "\n".join([*_render_one(kernel, symbol), *batch]) + "\n"
    digest = hashlib.sha256(f"{ABI_VERSION}\0{_PRELUDE}\0{code}".encode()).hexdigest()
    code += f'const char {symbol}_digest[] = "{digest}";\n'
    return _Generated(symbol, code, digest)


def generate_c(fn: casadi.Function, symbol: str) -> str:
    """Self-contained C source for ``fn`` with two entry points.

    ``void <symbol>_one(const double* in, double* out)``: one sample; ``in`` is all inputs
    densified (column-major, structural zeros included) and concatenated, ``out`` likewise for
    the outputs (structural zeros written as 0).  ``void <symbol>_batch(long n, const double*
    const* in, double* const* out, int nthreads)``: ``in[k]`` points to input k as
    struct-of-arrays (element j of sample i at ``in[k][j*n + i]``), ``out[k]`` likewise;
    ``nthreads > 1`` splits the samples over threads.  Inputs and outputs must not overlap
    (the kernels use ``restrict``).  Per-argument pointers (rather than one
    concatenated block) let contiguous batched arguments be passed without a copy.

    Raises :class:`NativeUnsupportedError` if an operation cannot be lowered.
    """
    return _PRELUDE + _function_c(fn, symbol).code


def generate_library_c(functions: Mapping[str, casadi.Function]) -> str:
    """One C translation unit for several functions; symbols from :func:`symbol_for`."""
    return _PRELUDE + "".join(_function_c(f, symbol_for(n)).code for n, f in functions.items())


def symbol_for(name: str) -> str:
    """Deterministic, collision-resistant C symbol for a function name."""
    tag = hashlib.sha1(name.encode()).hexdigest()[:8]
    return f"grace_{tag}_{re.sub(r'[^A-Za-z0-9_]', '_', name)[:48]}"


# --------------------------------------------------------------------------------------------
# Compilation and caching
# --------------------------------------------------------------------------------------------


def find_compiler() -> list[str] | None:
    """The C compiler command: ``$CC`` if set (``None`` if it does not exist), else cc/gcc/clang."""
    env = os.environ.get("CC")
    if env is not None:
        cmd = shlex.split(env)
        exe = shutil.which(cmd[0]) if cmd else None
        return [exe, *cmd[1:]] if exe else None
    for candidate in ("cc", "gcc", "clang"):
        exe = shutil.which(candidate)
        if exe:
            return [exe]
    return None


@lru_cache(maxsize=8)
def _compiler_identity(cmd: tuple[str, ...]) -> str:
    """First line of ``--version``; part of the cache key so a compiler upgrade rebuilds."""
    try:
        proc = subprocess.run([*cmd, "--version"], capture_output=True, text=True, timeout=30)
        return proc.stdout.splitlines()[0] if proc.stdout else proc.stderr.strip()
    except (OSError, subprocess.SubprocessError) as err:
        return f"unknown ({err})"


@lru_cache(maxsize=1)
def _cpu_fingerprint() -> str:
    """-march=native code is CPU specific; a shared cache dir must not mix CPUs."""
    text = ""
    with contextlib.suppress(OSError):
        text = Path("/proc/cpuinfo").read_text()
    keep = [ln for ln in text.splitlines() if ln.startswith(("model name", "flags"))][:2]
    return f"{platform.machine()}|{platform.processor()}|{'|'.join(keep)}"


def default_cache_dir() -> Path:
    """``native`` under the one cache root (:func:`grace_dsl.cache.cache_dir`)."""
    return cache_dir() / "native"


def _atomic_write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)


class BuildCancelled(Exception):
    """The caller asked a native build to stop (Ctrl-C during ``eacc build``)."""


Cancelled = Callable[[], bool]


def _compile(
    cmd: list[str],
    flags: Sequence[str],
    srcs: list[Path],
    target: Path,
    cancelled: Cancelled | None = None,
) -> str | None:
    """Run one compilation; returns the error text or None on success.

    Polls ``cancelled`` while the compiler runs and kills it when asked, so an interrupted build
    stops within a fraction of a second instead of finishing a long compilation.
    """
    argv = [*cmd, *flags, *_LINK_FLAGS, "-o", str(target), *map(str, srcs), "-lm"]
    try:
        # Its own process group: killing the driver alone would leave cc1 and as running.
        proc = subprocess.Popen(
            argv,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
    except OSError as err:
        return str(err)
    with proc:
        waited = 0.0
        while True:
            try:
                _, stderr = proc.communicate(timeout=0.1)
                break
            except subprocess.TimeoutExpired:
                waited += 0.1
                if (cancelled is not None and cancelled()) or waited > _COMPILE_TIMEOUT_S:
                    with contextlib.suppress(ProcessLookupError):
                        os.killpg(proc.pid, signal.SIGKILL)
                    proc.communicate()
                    if cancelled is not None and cancelled():
                        raise BuildCancelled(str(target)) from None
                    return f"timed out after {_COMPILE_TIMEOUT_S:.0f} s"
    return None if proc.returncode == 0 else (stderr.strip() or f"exit {proc.returncode}")


def build_shared_library(
    sources: Mapping[str, str] | str,
    out_dir: Path,
    name: str,
    cancelled: Cancelled | None = None,
) -> Path | None:
    """Compile C ``sources`` (text, or file name -> text) into ``out_dir/<name>.so``.

    Returns ``None`` (and logs why) if no compiler exists or compilation fails, so the caller
    can fall back to CasADi.  The library is written to a temporary file and renamed into place,
    so concurrent builders never expose a half-written ``.so``.  Tries :data:`FLAG_TIERS` in order.
    """
    cmd = find_compiler()
    if cmd is None:
        logger.info("no C compiler found (CC=%r); using CasADi's VM", os.environ.get("CC"))
        return None
    files = {f"{name}.c": sources} if isinstance(sources, str) else dict(sources)
    try:
        return _build(cmd, files, out_dir, name, cancelled)
    except OSError as err:  # unwritable cache dir, disk full, ...
        logger.warning("native build of %s failed (%s); using CasADi's VM", name, err)
        return None


def _build(
    cmd: list[str], files: dict[str, str], out_dir: Path, name: str, cancelled: Cancelled | None
) -> Path | None:
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{name}.so"
    # Sources beside the target: an interrupted build leaves nothing behind in /tmp.
    with tempfile.TemporaryDirectory(prefix=".grace_native_", dir=out_dir) as tmp:
        srcs = [Path(tmp) / fname for fname in files]
        for path, text in zip(srcs, files.values(), strict=True):
            path.write_text(text)
        fd, tmp_so = tempfile.mkstemp(dir=out_dir, prefix=f".{name}.", suffix=".so.tmp")
        os.close(fd)
        errors = []
        try:
            for flags in FLAG_TIERS:
                error = _compile(cmd, flags, srcs, Path(tmp_so), cancelled)
                if error is None:
                    os.replace(tmp_so, target)
                    return target
                errors.append(error)
        finally:
            Path(tmp_so).unlink(missing_ok=True)
    logger.warning("native build of %s failed; using CasADi's VM:\n%s", name, errors[-1][-2000:])
    return None


def toolchain_fingerprint() -> str:
    """What, besides the C source, decides the bytes of a library: compiler, flags, CPU, ABI."""
    cmd = find_compiler() or ["<none>"]
    parts = [
        _compiler_identity(tuple(cmd)),
        repr(FLAG_TIERS),
        repr(_LINK_FLAGS),
        _cpu_fingerprint(),
        str(ABI_VERSION),
    ]
    return "\0".join(parts)


def _library_key(source: str) -> str:
    return hashlib.sha256(f"{source}\0{toolchain_fingerprint()}".encode()).hexdigest()[:24]


#: Names of the libraries this module writes (``grace_<key>.so``); nothing else is ever loaded.
LIBRARY_NAME = re.compile(r"grace_[0-9a-f]{24}\.so\Z")


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _digest_path(library: Path) -> Path:
    return library.with_name(library.name + ".sha256")


def _verified(library: Path) -> bool:
    """A library may be loaded: private (see grace_dsl.cache) and its bytes match the digest
    recorded when it was built, so a replaced or rebuilt ``.so`` is never ``dlopen``ed."""
    try:
        if untrusted_reason(library) is not None or not library.is_file():
            return False
        return _digest_path(library).read_text().strip() == file_sha256(library)
    except OSError:
        return False


def _build_cached(
    generated: Sequence[_Generated], out_dir: Path | None, cancelled: Cancelled | None = None
) -> Path | None:
    source = _PRELUDE + "".join(g.code for g in generated)
    out_dir = default_cache_dir() if out_dir is None else out_dir
    name = f"grace_{_library_key(source)}"
    target = out_dir / f"{name}.so"
    if _verified(target):
        return target
    reason = untrusted_reason(out_dir) if out_dir.exists() else None
    if reason is not None:  # what we would build there could be swapped before it is loaded
        logger.warning("not building native code in %s (%s); using CasADi's VM", out_dir, reason)
        return None
    built = build_shared_library(source, out_dir, name, cancelled)
    if built is not None:
        try:
            _atomic_write(_digest_path(built), file_sha256(built) + "\n")
        except OSError as err:
            logger.warning("cannot record the digest of %s (%s); using CasADi's VM", built, err)
            return None
        with contextlib.suppress(OSError):
            _atomic_write(out_dir / f"{name}.c", source)  # kept for inspection only
    return built


def _generate_all(
    functions: Mapping[str, casadi.Function], uniform: Mapping[str, frozenset[int]] | None = None
) -> dict[str, _Generated]:
    """C for every function that can be lowered; the others are logged and left to CasADi."""
    generated: dict[str, _Generated] = {}
    for name, fn in functions.items():
        try:
            once = (uniform or {}).get(name, _NONE)
            generated[name] = _function_c(fn, symbol_for(name), once)
        except NativeUnsupportedError as err:
            logger.info("%s stays on CasADi's VM: %s", name, err)
    return generated


def build_native_library(
    functions: Mapping[str, casadi.Function],
    out_dir: Path | None = None,
    cancelled: Cancelled | None = None,
) -> Path | None:
    """Compile ``functions`` into one cached ``.so`` named by a hash of code, compiler and flags.

    Functions that cannot be lowered are skipped (they stay on CasADi); ``fast_functions`` on
    the same functions and directory finds this library without invoking the compiler.
    Returns ``None`` if nothing can be lowered or compilation is impossible.
    """
    generated = _generate_all(functions)
    return _build_cached(list(generated.values()), out_dir, cancelled) if generated else None


# --------------------------------------------------------------------------------------------
# Evaluators
# --------------------------------------------------------------------------------------------


class Evaluator(Protocol):
    """Common interface of native and CasADi evaluators."""

    name: str
    backend: str

    def __call__(self, *args: ArrayLike) -> Outputs: ...

    def batch(self, *args: ArrayLike, threads: int | None = None) -> Outputs: ...


@lru_cache(maxsize=1)
def _usable_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _auto_threads(n: int, threads: int | None) -> int:
    if threads is not None:
        return max(1, threads)
    return max(1, min(_usable_cpus(), MAX_AUTO_THREADS, n // MIN_SAMPLES_PER_THREAD))


@dataclass
class _Buffers:
    """One thread's reusable single-sample buffers, with views and raw pointers precomputed."""

    inp: FloatArray
    in_views: list[FloatArray]
    out_views: list[FloatArray]
    in_ptr: ctypes.c_void_p
    out_ptr: ctypes.c_void_p

    @staticmethod
    def new(layout: _Layout) -> _Buffers:
        inp, out = np.zeros(max(1, layout.n_in)), np.zeros(max(1, layout.n_out))

        def views(buf: FloatArray, args: tuple[_Arg, ...]) -> list[FloatArray]:
            return [
                buf[a.offset : a.offset + a.size].reshape(a.rows, a.cols, order="F") for a in args
            ]

        return _Buffers(
            inp,
            views(inp, layout.inputs),
            views(out, layout.outputs),
            ctypes.c_void_p(inp.ctypes.data),
            ctypes.c_void_p(out.ctypes.data),
        )


_PTRS = ctypes.POINTER(ctypes.c_void_p)
_PY_SCALARS = frozenset((float, int, np.float64))


class NativeFunction:
    """A compiled kernel loaded with ctypes.

    ``__call__`` evaluates one sample.  It reuses preallocated buffers that are *per thread*
    (``threading.local``), so concurrent callers never share them, and calls the kernel through
    ``PyDLL`` without releasing the GIL (releasing costs more than the kernel).  It returns fresh
    arrays that never alias the buffers.  ``batch`` releases the GIL and may use native threads.
    """

    backend = "native"

    def __init__(
        self,
        fn: casadi.Function,
        libs: tuple[ctypes.CDLL, ctypes.CDLL],
        symbol: str,
        uniform: frozenset[int] = frozenset(),
    ) -> None:
        """``libs``: the library loaded as ``PyDLL`` (GIL held) and as ``CDLL`` (GIL released);
        ``uniform``: the inputs its batch kernel reads once for every sample."""
        self.name = fn.name()
        self._uniform = uniform
        self._layout = _Layout.of(fn)
        self._one = getattr(libs[0], f"{symbol}_one")
        self._one.argtypes = (ctypes.c_void_p, ctypes.c_void_p)
        self._one.restype = None
        self._batch = getattr(libs[1], f"{symbol}_batch")
        self._batch.argtypes = (ctypes.c_long, _PTRS, _PTRS, ctypes.c_int)
        self._batch.restype = None
        self._tls = threading.local()
        self._n_args = len(self._layout.inputs)
        self._scalar_args = all(a.size == 1 for a in self._layout.inputs)
        self._sample_shapes = tuple(a.sample_shapes for a in self._layout.inputs)
        # (offset, size, is a vector) per input: the fast copy of scalars and 1-D vectors
        self._slots = tuple(
            (a.offset, a.size, a.rows == 1 or a.cols == 1) for a in self._layout.inputs
        )

    def _buffers(self) -> _Buffers:
        buffers = _Buffers.new(self._layout)
        self._tls.buffers = buffers
        return buffers

    def __call__(self, *args: ArrayLike) -> Outputs:
        try:
            b: _Buffers = self._tls.buffers
        except AttributeError:
            b = self._buffers()
        if self._scalar_args and len(args) == self._n_args:
            inp = b.inp  # scalar inputs: offset k == argument k
            for k, value in enumerate(args):
                if type(value) in _PY_SCALARS:
                    inp[k] = value
                else:
                    b.in_views[k][...] = self._layout.sample(k, value)
        else:
            if len(args) != self._n_args:
                self._layout.check_arity(args)
            inp = b.inp
            for k, value in enumerate(args):
                offset, size, vector = self._slots[k]
                if type(value) in _PY_SCALARS and size == 1:
                    inp[offset] = value
                elif (
                    vector
                    and type(value) is np.ndarray
                    and value.ndim == 1
                    and value.shape[0] == size
                ):
                    inp[offset : offset + size] = value  # a vector's flat order is its own
                else:
                    b.in_views[k][...] = self._layout.sample(k, value)
        self._one(b.in_ptr, b.out_ptr)
        if len(b.out_views) == 1:
            return b.out_views[0].copy()
        return tuple([v.copy() for v in b.out_views])  # a list is quicker than a generator

    def batch(self, *args: ArrayLike, threads: int | None = None) -> Outputs:
        """Evaluate N samples; each output has shape (N, r, c).

        Arguments with a single-sample shape are broadcast.  Outputs are transposed views of
        struct-of-arrays buffers (not C-contiguous); copy them if you need contiguity.
        ``threads`` defaults to one thread per :data:`MIN_SAMPLES_PER_THREAD` samples.
        Small batches of float64 arrays reuse this thread's buffers and return C-contiguous
        copies (see :meth:`_small_batch`).
        """
        if (threads is None or threads == 1) and not self._uniform:
            out = self._small_batch(args)
            if out is not None:
                return out
        n, split = self._layout.split_batch(args)
        blocks = []
        for k, (arg, (arr, batched)) in enumerate(zip(self._layout.inputs, split, strict=True)):
            if k not in self._uniform:
                blocks.append(_soa_block(arg, arr, batched, n))
            elif batched:
                raise ValueError(f"{self.name}: input {arg.name!r} is one value for every sample")
            else:  # read once by the kernel: one sample's elements, no copy per sample
                blocks.append(np.ascontiguousarray(arr.reshape(-1, order="F")))
        outs = [np.empty((a.size, n)) for a in self._layout.outputs]
        in_ptrs = (ctypes.c_void_p * max(1, len(blocks)))(*[b.ctypes.data for b in blocks])
        out_ptrs = (ctypes.c_void_p * max(1, len(outs)))(*[o.ctypes.data for o in outs])
        self._batch(n, in_ptrs, out_ptrs, _auto_threads(n, threads))
        return _pack(
            [
                o.reshape(a.cols, a.rows, n).transpose(2, 1, 0)
                for a, o in zip(self._layout.outputs, outs, strict=True)
            ]
        )

    def _small_batch(self, args: Sequence[ArrayLike]) -> Outputs | None:
        """``batch`` for up to :data:`SMALL_BATCH` samples of float64 arrays, or None.

        Why: for a handful of samples (a grasp family's 16 poses) the generic path's array
        conversions and ctypes pointer arrays cost ten times the kernel. Here the per-thread
        struct-of-arrays buffers and their pointer arrays are made once per N and refilled;
        anything unusual (other types, bad shapes, large N) returns None, and the generic path
        handles or rejects it.
        """
        if len(args) != self._n_args:
            return None
        n = -1  # no batched argument yet
        for shapes, value in zip(self._sample_shapes, args):
            if type(value) is not np.ndarray or value.dtype != np.float64:
                return None
            if value.shape not in shapes:
                if value.ndim == 0 or value.shape[1:] not in shapes:
                    return None
                if n >= 0 and value.shape[0] != n:
                    return None
                n = value.shape[0]
        n = 1 if n < 0 else n
        if not 0 < n <= SMALL_BATCH:
            return None
        cache = getattr(self._tls, "small", None)
        if cache is None:
            cache = self._tls.small = {}
        bufs = cache.get(n)
        if bufs is None:
            if len(cache) >= 4:
                cache.pop(next(iter(cache)))
            bufs = cache[n] = _SmallBuffers.new(self._layout, n)
        arrays = cast("Sequence[FloatArray]", args)  # all float64 arrays, checked above
        for arg, value, block in zip(self._layout.inputs, arrays, bufs.blocks):
            if value.ndim <= 1 and value.shape in arg.sample_shapes:
                block.T[...] = value  # a scalar or vector, the same for every sample
            elif value.shape in arg.sample_shapes:
                block[...] = value.reshape(-1, order="F")[:, None]
            elif value.ndim == 2 and value.shape[1] == arg.size:
                block.T[...] = value  # (N, size): a scalar's or a vector's samples
            else:
                block.reshape(arg.cols, arg.rows, n)[...] = value.reshape(
                    n, arg.rows, arg.cols
                ).transpose(2, 1, 0)
        self._batch(n, bufs.in_ptrs, bufs.out_ptrs, 1)
        outs = [
            o.reshape(a.cols, a.rows, n).transpose(2, 1, 0).copy()
            for a, o in zip(self._layout.outputs, bufs.outs)
        ]
        return outs[0] if len(outs) == 1 else tuple(outs)


#: Largest batch served from reused per-thread buffers (larger ones allocate and may thread).
SMALL_BATCH = 1024


@dataclass
class _SmallBuffers:
    """Struct-of-arrays input and output blocks for N samples, with their pointer arrays."""

    blocks: list[FloatArray]
    outs: list[FloatArray]
    in_ptrs: Any
    out_ptrs: Any

    @staticmethod
    def new(layout: _Layout, n: int) -> _SmallBuffers:
        blocks = [np.empty((a.size, n)) for a in layout.inputs]
        outs = [np.empty((a.size, n)) for a in layout.outputs]
        return _SmallBuffers(
            blocks,
            outs,
            (ctypes.c_void_p * max(1, len(blocks)))(*[b.ctypes.data for b in blocks]),
            (ctypes.c_void_p * max(1, len(outs)))(*[o.ctypes.data for o in outs]),
        )


def _soa_block(arg: _Arg, arr: FloatArray, batched: bool, n: int) -> FloatArray:
    """An input as a contiguous (size, N) block; zero-copy for contiguous scalar batches."""
    if not batched:  # repeat: a tenth of broadcast_to + ascontiguousarray's cost for small N
        return arr.reshape(-1, order="F")[:, None].repeat(n, axis=1)
    if arg.size == 1:
        return np.ascontiguousarray(arr.reshape(1, n))
    block = np.empty((arg.size, n))
    block.reshape(arg.cols, arg.rows, n)[...] = arr.transpose(2, 1, 0)
    return block


class CasadiEvaluator:
    """Fallback evaluator on CasADi's VM with the same interface as :class:`NativeFunction`."""

    backend = "casadi"

    def __init__(self, fn: casadi.Function, threads: int = 2) -> None:
        self.name = fn.name()
        self._fn = fn
        self._layout = _Layout.of(fn)
        self._threads = threads
        self._maps: dict[tuple[int, int], casadi.Function] = {}

    def __call__(self, *args: ArrayLike) -> Outputs:
        self._layout.check_arity(args)
        res = self._fn.call([self._layout.sample(k, a) for k, a in enumerate(args)])
        return _pack([np.asarray(r.full(), dtype=np.float64) for r in res])

    def _map(self, n: int, threads: int) -> casadi.Function:
        key = (n, threads)
        if key not in self._maps:
            if len(self._maps) >= 4:
                self._maps.pop(next(iter(self._maps)))
            parallel = "thread" if threads > 1 else "serial"
            self._maps[key] = (
                self._fn.map(n, parallel, threads) if threads > 1 else self._fn.map(n, parallel)
            )
        return self._maps[key]

    def batch(self, *args: ArrayLike, threads: int | None = None) -> Outputs:
        """Evaluate N samples with ``Function.map``; each output has shape (N, r, c)."""
        n, split = self._layout.split_batch(args)
        if n == 0:
            return _pack([np.empty((0, a.rows, a.cols)) for a in self._layout.outputs])
        mapped = [
            arr.transpose(1, 0, 2).reshape(a.rows, n * a.cols) if batched else arr
            for a, (arr, batched) in zip(self._layout.inputs, split, strict=True)
        ]
        res = self._map(n, self._threads if threads is None else threads).call(mapped)
        return _pack(
            [
                np.asarray(r.full()).reshape(a.rows, n, a.cols).transpose(1, 0, 2)
                for a, r in zip(self._layout.outputs, res, strict=True)
            ]
        )


def _load(
    path: Path,
    functions: Mapping[str, casadi.Function],
    generated: Mapping[str, _Generated],
    uniform: Mapping[str, frozenset[int]] | None = None,
) -> dict[str, NativeFunction]:
    libs = (ctypes.PyDLL(str(path)), ctypes.CDLL(str(path)))
    loaded: dict[str, NativeFunction] = {}
    for name, fn in functions.items():
        gen = generated[name]
        try:
            found = (ctypes.c_char * (len(gen.digest) + 1)).in_dll(libs[1], f"{gen.symbol}_digest")
        except ValueError as err:
            raise ValueError(f"{path}: no kernel for {name!r}") from err
        if found.value.decode() != gen.digest:
            raise ValueError(f"{path}: kernel for {name!r} is stale")
        loaded[name] = NativeFunction(fn, libs, gen.symbol, (uniform or {}).get(name, _NONE))
    return loaded


def load_native_library(
    path: Path, functions: Mapping[str, casadi.Function]
) -> dict[str, NativeFunction]:
    """Wrap the kernels of a library built by :func:`build_native_library`.

    Returns one :class:`NativeFunction` per function that can be lowered.  Regenerates each
    function's code and compares its digest with the one in the library; raises
    :class:`ValueError` on mismatch, so a stale library is never used silently. ``path`` is
    loaded as given: trusting it is the caller's decision (see ``grace_dsl.cache``).
    """
    generated = _generate_all(functions)
    return _load(path, {n: functions[n] for n in generated}, generated)


def fast_functions(
    functions: Mapping[str, casadi.Function],
    cache_dir: Path | None = None,
    *,
    native: bool = True,
    uniform: Mapping[str, frozenset[int]] | None = None,
) -> dict[str, Evaluator]:
    """Best evaluator for each function; all native ones share one cached ``.so``.

    Functions that cannot be lowered, or all of them when no compiler works (or ``native`` is
    false), get a :class:`CasadiEvaluator`. ``uniform`` (function name -> input indices):
    inputs that ``batch`` always gets as one value for every sample; the kernel reads them once
    instead of from a copy per sample (what costs most when they are large and the per-sample
    work is small), and ``batch`` refuses a batched value for them.
    """
    result: dict[str, Evaluator] = {n: CasadiEvaluator(f) for n, f in functions.items()}
    generated = _generate_all(functions, uniform) if native else {}
    path = _build_cached(list(generated.values()), cache_dir) if generated else None
    if path is None:
        return result
    if not _verified(path):
        logger.warning("not loading %s: %s", path, untrusted_reason(path) or "digest mismatch")
        return result
    try:
        result.update(_load(path, {n: functions[n] for n in generated}, generated, uniform))
    except (OSError, ValueError) as err:
        logger.warning("cannot load %s (%s); using CasADi's VM", path, err)
    return result


def load_unit_library(path: Path, functions: Mapping[str, casadi.Function]) -> dict[str, Evaluator]:
    """Evaluators for a unit's functions: its library's kernels, CasADi's VM for the rest.

    The caller has checked the library's bytes and ownership. A library built for another
    compiler or CPU (an artifact copied between machines) is not loaded: ``-march=native`` code
    may not run here.
    """
    result: dict[str, Evaluator] = {n: CasadiEvaluator(f) for n, f in functions.items()}
    generated = _generate_all(functions)
    source = _PRELUDE + "".join(g.code for g in generated.values())
    if path.name != f"grace_{_library_key(source)}.so":
        logger.warning("%s was built by another compiler or CPU; using CasADi's VM", path)
        return result
    result.update(_load(path, {n: functions[n] for n in generated}, generated))
    return result


def fast_function(
    fn: casadi.Function, cache_dir: Path | None = None, *, native: bool = True
) -> Evaluator:
    """Best evaluator for ``fn``: compiled C if possible, else CasADi's VM."""
    return fast_functions({fn.name(): fn}, cache_dir, native=native)[fn.name()]
