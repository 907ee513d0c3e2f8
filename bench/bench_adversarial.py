"""The adversarial suite: bad inputs thrown at every boundary, counted by how they end.

Every case feeds one bad input to the runtime API, the front end, the command line or the cache,
and ends in one of five ways:

- ``typed``: a ``GraceError`` subclass (API) or a located diagnostic / one-line error (CLI);
- ``ok``: a result that is right (finite, or equal to what an untouched run gives);
- ``traceback``: any other exception, or a Python traceback on a command's stderr;
- ``hang``: no answer within the case's time bound;
- ``wrong``: a result that is silently wrong (accepted although it must be refused, non-finite,
  or different from the untouched run; code planted in the cache ran).

The figure this prints ("N bad inputs tried, 0 tracebacks, 0 hangs, 0 silent wrong results") is
the one recorded in docs/benchmarks.md.  Exit status 1 when any case ends badly.

    python bench/bench_adversarial.py               # the whole suite
    python bench/bench_adversarial.py --smoke       # every 12th case (the test suite runs this)
    python bench/bench_adversarial.py --json        # one record per case on stdout
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CONCEPTS = ROOT / "concepts"
RESULTS = ROOT / "bench" / "results" / "adversarial.json"
API_TIMEOUT_S = 20
CLI_TIMEOUT_S = 60
BAD = ("traceback", "hang", "wrong")
EACC = [sys.executable, "-c", "import sys; from grace_dsl.cli.eacc import main; sys.exit(main())"]


@dataclass(frozen=True)
class Case:
    group: str
    name: str
    run: Callable[[], str]  # returns an outcome; raising is judged by the runner


@dataclass(frozen=True)
class Record:
    group: str
    name: str
    outcome: str
    detail: str
    seconds: float


class _Timeout(Exception):
    pass


# --------------------------------------------------------------------------------------------
# Judging
# --------------------------------------------------------------------------------------------


def _finite(value: Any) -> bool:
    """True when every number in ``value`` (arrays, tuples, dicts, objects' arrays) is finite."""
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(_finite(v) for v in value)
    if isinstance(value, (float, int, np.ndarray, np.generic)) and not isinstance(value, bool):
        return bool(np.all(np.isfinite(np.asarray(value, dtype=float))))
    return True


def _api(call: Callable[[], Any], must_reject: bool) -> Callable[[], str]:
    """A runtime case: a GraceError is right; a result is right only if finite and allowed."""

    def run() -> str:
        import grace_dsl as eac

        try:
            value = call()
        except eac.GraceError:
            return "typed"
        if must_reject:
            return "wrong"
        return "ok" if _finite(value) else "wrong"

    return run


def _run_one(case: Case) -> Record:
    start = time.perf_counter()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(API_TIMEOUT_S if case.group in ("api", "source") else CLI_TIMEOUT_S * 3)
    try:
        outcome, detail = case.run(), ""
    except _Timeout:
        outcome, detail = "hang", f"no answer in {API_TIMEOUT_S} s"
    except Exception as exc:  # the suite's whole point: every escape is counted
        outcome, detail = "traceback", f"{type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    if outcome.startswith(BAD) and ":" in outcome:
        outcome, detail = outcome.split(":", 1)
    return Record(case.group, case.name, outcome, detail, time.perf_counter() - start)


def _alarm(signum: int, frame: Any) -> None:
    raise _Timeout


# --------------------------------------------------------------------------------------------
# The runtime API
# --------------------------------------------------------------------------------------------

BAD_NUMBERS: list[Any] = [
    10**400,
    -(10**400),
    float("nan"),
    float("inf"),
    -float("inf"),
    "0.05",
    b"0.05",
    None,
    "abc",
    [0.1, 0.2],
    {"a": 1},
    object(),
    True,
    1e300,
    -1e300,
    complex(1, 1),
    [],
    (),
    [[0.1]],
]
BAD_COUNTS: list[Any] = [
    0,
    -1,
    10**9,
    10**30,
    2.5,
    "16",
    None,
    float("nan"),
    float("inf"),
    True,
    [4],
    -(10**9),
]
BAD_POSES: list[Any] = [
    "identity",
    None,
    3,
    [[1, 0, 0], [0, 1, 0]],
    [[1, 0], [0, 1, 0, 0]],
    np.full((4, 4), np.nan),
    np.diag([1.0, 1.0, -1.0, 1.0]),
    np.diag([2.0, 2.0, 2.0, 1.0]),
    np.zeros((4, 4)),
    np.eye(4) * 1e300,
    [[1, 0, 0, float("inf")]],
    np.eye(3),
    np.eye(5),
    "G",
    b"\x00",
    {"R": 1},
]
BAD_POINTS: list[Any] = [
    [[1e300, 0, 0]],
    [[float("nan"), 0, 0]],
    [[0, 0]],
    [0, 0, 0],
    "points",
    None,
    np.zeros((0, 3)),
    [[0, 0, 0], [1, 1]],
    [["a", "b", "c"]],
    np.full((2, 3), np.inf),
    [[1e308, 1e308, 1e308]],
]
BAD_NAMES: list[Any] = [123, None, "", "nope", b"pull", ("pull",), "PULL", "pull\x1b[2J", 1.5]


def _library() -> Any:
    import grace_dsl as eac

    return eac.load_library()


def api_cases(lib: Any) -> Iterator[Case]:
    """Bad values at every argument of the public runtime API, on a few library concepts."""
    for key in BAD_NAMES:
        yield Case("api", f"lib[{key!r}]", _api(lambda k=key: lib[k], True))
    for cname in ("CurveHandle", "SunkenDoor", "ChestOfDrawers", "RoundKnob", "Refrigerator"):
        concept = lib[cname]
        yield from _param_cases(concept)
        inst = concept.instantiate()
        yield from _joint_cases(concept)
        yield from _pose_cases(concept)
        yield from _grasp_cases(cname, inst)
        yield from _action_cases(cname, inst)
        yield from _geometry_cases(cname, inst)


def _param_cases(concept: Any) -> Iterator[Case]:
    for spec in concept.params:
        for value in BAD_NUMBERS:
            fits = spec.kind == "vec" and isinstance(value, list) and len(value) == spec.size
            must = not fits  # every other value is refused: wrong type, not finite, out of range
            yield Case(
                "api",
                f"{concept.name}.instantiate({spec.name}={value!r:.40})",
                _api(lambda s=spec, v=value: concept.instantiate(**{s.name: v}), must),
            )
    yield Case(
        "api",
        f"{concept.name}.instantiate(nope=1)",
        _api(lambda: concept.instantiate(nope=1), True),
    )


def _joint_cases(concept: Any) -> Iterator[Case]:
    names = list(concept.moving_joints) or ["hinge"]
    for value in [*BAD_NUMBERS, -0.5, 100.0]:
        yield Case(
            "api",
            f"{concept.name}.instantiate(joints={{{names[0]!r}: {value!r:.40}}})",
            _api(lambda v=value: concept.instantiate(joints={names[0]: v}), True),
        )
    for joints in ({1: 0.3}, "hinge", [0.3], {None: 0.1}, {names[0]: 0.1, "ghost": 0.0}):
        yield Case(
            "api",
            f"{concept.name}.instantiate(joints={joints!r})",
            _api(lambda j=joints: concept.instantiate(joints=j), True),
        )


def _pose_cases(concept: Any) -> Iterator[Case]:
    for i, pose in enumerate(BAD_POSES):
        if pose is None:  # no pose is the identity, on purpose
            continue
        yield Case(
            "api",
            f"{concept.name}.instantiate(pose=<bad pose {i}>)",
            _api(lambda m=pose: concept.instantiate(pose=m), True),
        )


def _grasp_cases(cname: str, inst: Any) -> Iterator[Case]:
    grasp = next(iter(inst.concept.grasps))
    free = list(inst.grasp_range(grasp))
    for key in BAD_NAMES:
        yield Case("api", f"{cname}.grasp({key!r})", _api(lambda k=key: inst.grasp(k), True))
    for value in BAD_NUMBERS if free else []:
        yield Case(
            "api",
            f"{cname}.grasp({grasp!r}, {free[0]}={value!r:.40})",
            _api(lambda v=value: inst.grasp(grasp, **{free[0]: v}), True),
        )
    for n in BAD_COUNTS:
        yield Case(
            "api",
            f"{cname}.grasps({grasp!r}, n={n!r})",
            _api(lambda n=n: inst.grasps(grasp, n), True),
        )
    for ref in BAD_POSES[:6]:
        yield Case(
            "api",
            f"{cname}.grasps({grasp!r}, reference=<bad>)",
            _api(lambda r=ref: inst.grasps(grasp, 4, reference=r), False),
        )


def _action_cases(cname: str, inst: Any) -> Iterator[Case]:
    action = next(iter(inst.concept.actions))
    grasp = inst.grasp(next(iter(inst.concept.grasps)))
    for key in BAD_NAMES:
        yield Case(
            "api", f"{cname}.force({key!r})", _api(lambda k=key: inst.force(k, grasp=grasp), True)
        )
    for i, pose in enumerate(BAD_POSES):
        yield Case(
            "api",
            f"{cname}.force({action!r}, grasp=<bad pose {i}>)",
            _api(lambda m=pose: inst.force(action, grasp=m), True),
        )
    for to in [*BAD_NUMBERS, -1.0, 1e9]:
        yield Case(
            "api",
            f"{cname}.follow({action!r}, to={to!r:.40})",
            _api(lambda t=to: inst.follow(action, grasp=grasp, to=t), True),
        )
    for steps in BAD_COUNTS:
        yield Case(
            "api",
            f"{cname}.follow({action!r}, steps={steps!r})",
            _api(lambda s=steps: inst.follow(action, grasp=grasp, to=0.1, steps=s), True),
        )
    for samples in BAD_COUNTS:
        yield Case(
            "api",
            f"{cname}.rank({action!r}, samples={samples!r})",
            _api(lambda s=samples: inst.rank(action, samples=s), True),
        )
    for gripper in ("x", 3, object(), {"width": -1}):
        yield Case(
            "api",
            f"{cname}.rank({action!r}, gripper={gripper!r:.30})",
            _api(lambda g=gripper: inst.rank(action, gripper=g), True),
        )


def _geometry_cases(cname: str, inst: Any) -> Iterator[Case]:
    for i, points in enumerate(BAD_POINTS):
        must = i not in (0, 6, 10)  # far points and an empty set have honest answers
        yield Case(
            "api", f"{cname}.sdf(<bad points {i}>)", _api(lambda p=points: inst.sdf(p), must)
        )
    for n in BAD_COUNTS:
        yield Case(
            "api",
            f"{cname}.sample_surface({n!r})",
            _api(lambda n=n: inst.sample_surface(n), n != 0),
        )
    for seed in (-1, 2.5, "0", None, float("nan")):
        yield Case(
            "api",
            f"{cname}.sample_surface(8, seed={seed!r})",
            _api(lambda s=seed: inst.sample_surface(8, seed=s), True),
        )
    for res in (0, -3, 10**9, 2.5, "64", None):
        yield Case(
            "api", f"{cname}.mesh(resolution={res!r})", _api(lambda r=res: inst.mesh(r), True)
        )
    for key in BAD_NAMES:
        yield Case(
            "api", f"{cname}.link_pose({key!r})", _api(lambda k=key: inst.link_pose(k), True)
        )


# --------------------------------------------------------------------------------------------
# The front end: mutated sources must give diagnostics, never an exception
# --------------------------------------------------------------------------------------------


def _front_end_case(text: str | bytes, name: str) -> Callable[[], str]:
    def run() -> str:
        from grace_dsl.compiler.build import front_end

        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "m.eac"
            path.write_bytes(text if isinstance(text, bytes) else text.encode())
            front_end([path])  # diagnostics are values; an exception escapes to the runner
        return "typed"

    return run


def _mutations(text: str, rng: random.Random) -> Iterator[tuple[str, str | bytes]]:
    data = text.encode()
    for _ in range(6):
        cut = rng.randrange(1, len(data))
        yield f"truncated at byte {cut}", data[:cut]
    for _ in range(4):
        at = rng.randrange(len(data))
        junk = bytes(rng.choice(b"{}()[]<>=*/+-.,;:#@\"'\\\x00\x1b\xff\xfe") for _ in range(3))
        yield f"junk {junk!r} at byte {at}", data[:at] + junk + data[at:]
    lines = text.splitlines(keepends=True)
    for _ in range(4):
        i = rng.randrange(len(lines))
        yield f"line {i + 1} dropped", "".join(lines[:i] + lines[i + 1 :])
    for _ in range(2):
        i = rng.randrange(len(lines))
        yield f"line {i + 1} doubled", "".join(lines[: i + 1] + lines[i:])


HANDWRITTEN_SOURCES = {
    "use of itself": "use m.{A}\nconcept A { param x : length in [0mm, 1mm] = 0mm }\n",
    "130 chained lets": "concept A {\n  param x : length in [1mm, 2mm] = 1mm\n  let l0 = x\n"
    + "".join(f"  let l{i} = l{i - 1} + 1mm\n" for i in range(1, 130))
    + "  require l129 > 0mm\n}\n",
    "NaN range bound": "concept A { param x : length in [0mm/0, 1mm] = 0mm }\n",
    "division by zero in range": "use primitives.{Cuboid}\nconcept A {\n"
    "  param r : length in [0mm, 10mm] = 5mm\n"
    "  grasp g(t in [0, 1] = 0) = trans(1mm*1mm/r, 0, 0)\n}\n",
    "sqrt of negative": "concept A {\n  param r : length in [-10mm, 10mm] = 5mm\n"
    "  grasp g(t in [0, 1] = 0) = trans(sqrt(r*1mm), 0, 0)\n}\n",
    "power overflow": "concept A {\n  param n : scalar in [0, 1000] = 1\n"
    "  grasp g(t in [0, 1] = 0) = trans(1mm * 10^n, 0, 0)\n}\n",
    "deep nesting": "concept A { let x = " + "(" * 5000 + "1mm" + ")" * 5000 + " }\n",
    "1 MB of a name": "concept " + "A" * 1_000_000 + " { }\n",
    "stray doc comment": "concept A {\n  param x : length in [0mm, 1mm] = 0mm\n  ///\n}\n",
    "angle without unit": "concept A {\n  grasp g(t in [0, 1] = 0) = rotx(90)\n}\n",
    "BOM": "\ufeffconcept A { param x : length in [0mm, 1mm] = 0mm }\n",
    "invalid UTF-8": b"concept A { param x : length in [0mm, 1mm] = 0mm \xff\xfe }\n",
    "NUL bytes": b"concept A {\x00\x00 }\n",
    "control characters in a doc": "/// \x1b]0;pwned\x07 \x1b[2J\nconcept A { }\n",
    "rich markup in a help": 'concept A { param x : length in [0mm, 1mm] = 0mm "[/] [link=x]y" }\n',
}


def source_cases(seed: int) -> Iterator[Case]:
    rng = random.Random(seed)
    for name, text in HANDWRITTEN_SOURCES.items():
        yield Case("source", name, _front_end_case(text, name))
    for path in sorted(CONCEPTS.glob("*.eac")):
        for what, text in _mutations(path.read_text(), rng):
            yield Case("source", f"{path.name}: {what}", _front_end_case(text, what))


BUILT_SOURCES = (
    "130 chained lets",
    "NaN range bound",
    "division by zero in range",
    "sqrt of negative",
    "power overflow",
    "angle without unit",
)


def _build_case(text: str) -> Callable[[], str]:
    """Programs that pass the front end must build, and evaluate finitely across their ranges."""

    def run() -> str:
        import grace_dsl as eac

        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "m.eac"
            path.write_text(text)
            try:
                lib = eac.compile_paths([path])
            except eac.CompileError:
                return "typed"
            verdicts = [_api(call, False)() for call in _range_calls(lib["A"])]
        bad = [v for v in verdicts if v != "ok" and v != "typed"]
        return bad[0] if bad else ("typed" if "typed" in verdicts else "ok")

    return run


def _range_calls(concept: Any) -> Iterator[Callable[[], Any]]:
    """Instantiate at each parameter's bounds and default; evaluate every grasp and limit there."""
    points = [{}] + [{s.name: v} for s in concept.params if s.kind == "num" for v in (s.lo, s.hi)]
    for values in points:

        def evaluate(values: dict[str, Any] = values) -> list[Any]:
            inst = concept.instantiate(**values)
            out: list[Any] = [inst.joint_limits()]
            for name in concept.grasps:
                out.append(inst.grasps(name, 5))
                out.append(inst.grasp(name))
            return out

        yield evaluate


def build_cases() -> Iterator[Case]:
    for name in BUILT_SOURCES:
        yield Case("build", name, _build_case(HANDWRITTEN_SOURCES[name]))


# --------------------------------------------------------------------------------------------
# The command line: exit codes 0/1/2 and no traceback, in bounded time
# --------------------------------------------------------------------------------------------


def _eacc(args: list[str], cwd: Path, env: dict[str, str] | None = None) -> tuple[int, str, str]:
    proc = subprocess.run(
        [*EACC, *args],
        cwd=cwd,
        env={**os.environ, **(env or {})},
        capture_output=True,
        text=True,
        errors="replace",
        timeout=CLI_TIMEOUT_S,
        stdin=subprocess.DEVNULL,
    )
    return proc.returncode, proc.stdout, proc.stderr


def _cli(setup: Callable[[Path], list[str]], check: Callable[[int, str, str], str] | None = None):
    """A command-line case: ``setup`` lays out files in a temp dir and returns eacc's arguments."""

    def run() -> str:
        with tempfile.TemporaryDirectory() as tmp:
            cwd = Path(tmp)
            args = setup(cwd)
            before = _snapshot(cwd)
            try:
                code, out, err = _eacc(args, cwd)
            except subprocess.TimeoutExpired:
                return f"hang:eacc {' '.join(args)} gave no answer in {CLI_TIMEOUT_S} s"
            if "Traceback" in err or "Traceback" in out:
                return "traceback:" + err.strip().splitlines()[-1][:200]
            if code not in (0, 1, 2):
                return f"traceback:exit {code}"
            if "\x1b]" in out + err or "\x1b[2J" in out + err:
                return "wrong:a control sequence from user text reached the terminal"
            if "root:x:0:0" in out + err:
                return "wrong:the contents of a file behind a symlink were printed"
            verdict = check(code, out, err) if check else None
            if verdict:
                return verdict
            if _snapshot(cwd, only=before) != before and code != 0:
                return "wrong:a failed command changed the user's files"
            return "typed" if code else "ok"

    return run


def _snapshot(root: Path, only: dict[str, bytes] | None = None) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    for path in sorted(root.rglob("*")):
        key = str(path.relative_to(root))
        if only is not None and key not in only:
            continue
        if path.is_file() and not path.is_symlink() and not path.is_fifo():
            out[key] = path.read_bytes()
    return out


def _write(cwd: Path, name: str, text: str | bytes) -> Path:
    path = cwd / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


GOOD = 'concept A {\n  param x : length in [0mm, 1mm] = 0mm "x"\n}\n'


def cli_cases() -> Iterator[Case]:
    def fifo(cwd: Path) -> list[str]:
        os.mkfifo(cwd / "x.eac")
        return ["check", "."]

    def fifo_fmt(cwd: Path) -> list[str]:
        os.mkfifo(cwd / "x.eac")
        return ["fmt", "x.eac"]

    def loop(cwd: Path) -> list[str]:
        os.symlink("loop.eac", cwd / "loop.eac")
        return ["check", "loop.eac"]

    def dangling(cwd: Path) -> list[str]:
        os.symlink("nowhere.eac", cwd / "d.eac")
        return ["fmt", "d.eac"]

    def directory(cwd: Path) -> list[str]:
        (cwd / "dir.eac").mkdir()
        return ["fmt", "dir.eac"]

    def readonly(cwd: Path) -> list[str]:
        path = _write(cwd, "r.eac", "concept   A {  }\n")
        path.chmod(0o444)
        return ["fmt", "r.eac"]

    def bad_utf8(cwd: Path) -> list[str]:
        _write(cwd, "u.eac", b"concept A { \xff }\n")
        return ["fmt", "u.eac"]

    def passwd(cwd: Path) -> list[str]:
        os.symlink("/etc/passwd", cwd / "passwd.eac")
        _write(cwd, "m.eac", "use passwd.{A}\nconcept B { }\n")
        return ["check", "m.eac"]

    def nested_json(cwd: Path) -> list[str]:
        _write(cwd, "i.json", "[" * 100_000)
        return ["export", "CurveHandle", "--urdf", "o.urdf", "--instance-json", "i.json"]

    def prompt_readonly(cwd: Path) -> list[str]:
        (cwd / "ro").mkdir()
        (cwd / "ro").chmod(0o555)
        return ["prompt", "-o", "ro/catalog.md"]

    def escapes(cwd: Path) -> list[str]:
        _write(
            cwd,
            "e.eac",
            "/// \x1b]0;pwned\x07 title\nconcept E {\n  param x : length in "
            '[0mm, 1mm] = 0mm "\x1b[2J [/] [link=http://x]y[/link]"\n}\n',
        )
        return ["explain", "E", "e.eac"]

    def diag_escapes(cwd: Path) -> list[str]:
        _write(cwd, "e.eac", "concept E {\n  param \x1b]0;pwned\x07 : length\n}\n")
        return ["check", "e.eac"]

    def missing(cwd: Path) -> list[str]:
        return ["check", "nothing.eac"]

    def bad_joint(cwd: Path) -> list[str]:
        return ["export", "SunkenDoor", "--urdf", "o.urdf", "--joint", "hinge=lots"]

    def bad_pose(cwd: Path) -> list[str]:
        return ["export", "SunkenDoor", "--urdf", "o.urdf", "--pose", "1,2"]

    def unknown(cwd: Path) -> list[str]:
        return ["explain", "NoSuchConcept"]

    def usage(cwd: Path) -> list[str]:
        return ["build", "--no-such-flag"]

    for setup in (
        fifo,
        fifo_fmt,
        loop,
        dangling,
        directory,
        readonly,
        bad_utf8,
        passwd,
        nested_json,
        prompt_readonly,
        escapes,
        diag_escapes,
        missing,
        bad_joint,
        bad_pose,
        unknown,
        usage,
    ):
        yield Case("cli", setup.__name__, _cli(setup))
    yield Case("cli", "fmt under a file-size limit", _fmt_under_limit)


def _fmt_under_limit() -> str:
    """``eacc fmt`` with RLIMIT_FSIZE below the file's size must leave the file untouched."""
    source = (CONCEPTS / "handles.eac").read_text()
    ugly = source.replace("    ", "  ")  # needs reformatting, so fmt writes
    with tempfile.TemporaryDirectory() as tmp:
        path = _write(Path(tmp), "h.eac", ugly)
        limit = len(ugly.encode()) // 2

        def cap() -> None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

        try:
            proc = subprocess.run(
                [*EACC, "fmt", str(path)],
                capture_output=True,
                text=True,
                timeout=CLI_TIMEOUT_S,
                preexec_fn=cap,
                stdin=subprocess.DEVNULL,
            )
        except subprocess.TimeoutExpired:
            return "hang:fmt under a size limit"
        if path.read_text() != ugly:
            return "wrong:fmt left a changed file after a failed write"
        if "Traceback" in proc.stderr:
            return "traceback:" + proc.stderr.strip().splitlines()[-1][:200]
        return "typed" if proc.returncode else "wrong:fmt said it succeeded but wrote nothing"


# --------------------------------------------------------------------------------------------
# The cache: planted code never runs, damaged units are never half-used
# --------------------------------------------------------------------------------------------

TINY = textwrap.dedent(
    """\
    concept Tiny {
        param a : length in [10mm, 100mm] = 50mm "offset"
        grasp g(t in [0, 1] = 0.5) = trans(a * t, a, 0) * rotz(30deg)
    }
    """
)

PROBE = textwrap.dedent(
    """\
    import json, sys
    import grace_dsl as eac
    try:
        lib = eac.compile_paths([sys.argv[1]])
        pose = lib["Tiny"].instantiate(a=0.04).grasp("g", t=0.25)
        print(json.dumps(pose.tolist()))
    except eac.GraceError as exc:
        print("REFUSED", str(exc).splitlines()[0])
    """
)


def _probe(cache: Path, src: Path) -> tuple[str, str]:
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, str(src)],
        env={**os.environ, "GRACE_CACHE_DIR": str(cache)},
        capture_output=True,
        text=True,
        timeout=CLI_TIMEOUT_S * 2,
        stdin=subprocess.DEVNULL,
    )
    return proc.stdout.strip(), proc.stderr


def _judge_probe(out: str, err: str, marker: Path) -> str:
    if marker.exists():
        return "wrong:code planted in the cache ran"
    if "Traceback" in err:
        return "traceback:" + err.strip().splitlines()[-1][:200]
    if out.startswith("REFUSED"):  # refusing is right only when it names the cache
        return "typed" if re.search(r"\bcache\b|\bunit\b", out) else f"wrong:{out[:200]}"
    try:
        pose = np.asarray(json.loads(out.splitlines()[-1]))
    except (ValueError, IndexError):
        return f"traceback:no result ({out[-200:]!r})"
    return "ok" if np.allclose(pose, _expected_pose(), atol=1e-12) else "wrong:a wrong grasp pose"


def _expected_pose() -> np.ndarray:
    """Tiny's grasp at a = 40 mm, t = 0.25, written out by hand."""
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    return np.array([[c, -s, 0, 0.01], [s, c, 0, 0.04], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _cache_case(poison: Callable[[Path, Path], None]) -> Callable[[], str]:
    """Warm a private cache with the tiny concept, poison it, and run the probe again."""

    def run() -> str:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            src = _write(root, "tiny.eac", TINY)
            cache, marker = root / "cache", root / "PLANTED-CODE-RAN"
            out, err = _probe(cache, src)
            if _judge_probe(out, err, marker) != "ok":
                return "traceback:the untouched cache did not work: " + (err or out)[-200:]
            poison(cache, marker)
            return _judge_probe(*_probe(cache, src), marker)

    return run


def _planted_library(marker: Path, out: Path) -> None:
    """A shared library whose constructor leaves ``marker``: proof that it was loaded."""
    c = out.with_suffix(".c")
    c.write_text(
        "#include <stdio.h>\n__attribute__((constructor)) static void planted(void) {\n"
        f'  FILE *f = fopen("{marker}", "w"); if (f) fclose(f);\n}}\n'
    )
    subprocess.run(["cc", "-shared", "-fPIC", "-o", str(out), str(c)], check=True)
    c.unlink()


def _each(cache: Path, pattern: str) -> list[Path]:
    return sorted(p for p in cache.rglob(pattern) if p.is_file())


def cache_cases() -> Iterator[Case]:
    def grammar_pickle(cache: Path, marker: Path) -> None:
        import pickle

        class Planted:
            def __reduce__(self) -> tuple[Any, ...]:
                return (os.system, (f"touch {marker}",))

        (cache / "eac-grammar.lark-cache").write_bytes(pickle.dumps(Planted()))  # the old name
        for found in _each(cache, "*lark*") + _each(cache / "grammar", "*"):
            found.write_bytes(pickle.dumps(Planted()))

    def replaced_so(cache: Path, marker: Path) -> None:
        for so in _each(cache, "*.so"):
            _planted_library(marker, so)

    def rebuilt_from_c(cache: Path, marker: Path) -> None:
        for c in _each(cache, "*.c"):
            text = c.read_text().replace("0.866025", "0.966025").replace("0.5", "0.6")
            so = c.with_suffix(".so")
            c.write_text(text)
            if so.exists():
                subprocess.run(
                    ["cc", "-shared", "-fPIC", "-O0", "-o", str(so), str(c), "-lm"],
                    check=False,
                    capture_output=True,
                )

    def garbage_so(cache: Path, marker: Path) -> None:
        for so in _each(cache, "*.so"):
            so.write_bytes(b"\x7fELF garbage")

    def truncated(name: str) -> Callable[[Path, Path], None]:
        def poison(cache: Path, marker: Path) -> None:
            for path in _each(cache, name):
                path.write_bytes(path.read_bytes()[: max(1, path.stat().st_size // 3)])

        poison.__name__ = f"truncated {name}"
        return poison

    def missing_unit_json(cache: Path, marker: Path) -> None:
        for path in _each(cache, "unit.json"):
            path.unlink()

    def edited_unit_json(cache: Path, marker: Path) -> None:
        for path in _each(cache, "unit.json"):
            data = json.loads(path.read_text())
            data["format"] = 999
            path.write_text(json.dumps(data))

    def edited_range(cache: Path, marker: Path) -> None:
        for path in _each(cache, "unit.json"):  # a = 40 mm falls outside the edited range
            data = json.loads(path.read_text())
            for entry in data.get("concepts", {}).values():
                for param in entry.get("params", []):
                    param["hi"] = 0.03
            path.write_text(json.dumps(data))

    def world_writable(cache: Path, marker: Path) -> None:
        for so in _each(cache, "*.so"):
            _planted_library(marker, so)
        for path in [cache, *cache.rglob("*")]:
            path.chmod(path.stat().st_mode | 0o022)

    for poison in (
        grammar_pickle,
        replaced_so,
        rebuilt_from_c,
        garbage_so,
        truncated("unit.json"),
        truncated("functions.json"),
        missing_unit_json,
        edited_unit_json,
        edited_range,
        world_writable,
    ):
        yield Case("cache", poison.__name__.replace("_", " "), _cache_case(poison))
    yield Case("cache", "artifact unit key with ../", _artifact_escape)


def _artifact_escape() -> str:
    """A manifest whose unit key climbs out of the artifact directory must be refused."""
    import grace_dsl as eac

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        src = _write(root, "tiny.eac", TINY)
        art = root / "art"
        proc = subprocess.run(
            [*EACC, "build", str(src), "-o", str(art)],
            env={**os.environ, "GRACE_CACHE_DIR": str(root / "cache")},
            capture_output=True,
            text=True,
            timeout=CLI_TIMEOUT_S * 2,
        )
        if proc.returncode != 0:
            return "traceback:build failed: " + proc.stderr[-200:]
        outside = root / "outside"
        units = sorted((art / "units").iterdir())
        shutil.move(str(units[0]), outside)
        manifest = json.loads((art / "manifest.json").read_text())
        key = units[0].name
        manifest["units"] = {"../../outside": next(iter(manifest["units"].values()))}
        for entry in manifest["concepts"].values():
            if entry.get("unit") == key:
                entry["unit"] = "../../outside"
        (art / "manifest.json").write_text(json.dumps(manifest))
        try:
            lib = eac.load_artifact(art)
            lib["Tiny"].instantiate().grasp("g")
        except eac.GraceError:
            return "typed"
        return "wrong:a unit outside the artifact directory was loaded"


# --------------------------------------------------------------------------------------------
# Running and reporting
# --------------------------------------------------------------------------------------------


def all_cases(seed: int) -> list[Case]:
    lib = _library()
    return [*api_cases(lib), *source_cases(seed), *build_cases(), *cli_cases(), *cache_cases()]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--smoke", action="store_true", help="every 12th case, and no result file")
    ap.add_argument("--seed", type=int, default=0, help="seed of the source mutations")
    ap.add_argument("--json", action="store_true", help="one JSON record per case on stdout")
    ap.add_argument("--out", type=Path, default=None, help=f"result file (default {RESULTS})")
    ap.add_argument("--group", nargs="*", default=None, help="only these groups (api source ...)")
    args = ap.parse_args(argv)

    cases = all_cases(args.seed)
    if args.group:
        cases = [c for c in cases if c.group in args.group]
    if args.smoke:
        cases = cases[::12]
    records = _run_all(cases, quiet=args.json)
    counts = Counter(r.outcome for r in records)
    summary = {
        "cases": len(records),
        "outcomes": dict(sorted(counts.items())),
        "by_group": _by_group(records),
        "seed": args.seed,
        "smoke": args.smoke,
    }
    if args.json:
        for r in records:
            print(json.dumps(r.__dict__))
    else:
        _print(records, summary)
    out = args.out or (None if args.smoke else RESULTS)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        bad = [r.__dict__ for r in records if r.outcome in BAD]
        out.write_text(json.dumps({**summary, "bad": bad}, indent=1) + "\n")
    return 1 if any(r.outcome in BAD for r in records) else 0


def _run_all(cases: list[Case], quiet: bool) -> list[Record]:
    # Allocations past a few GB are a defect the suite must see as an error, not a dead machine.
    limit = 6 * 2**30
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
    if quiet:
        return [_run_one(c) for c in cases]
    from rich.progress import Progress

    records = []
    with Progress(transient=True) as bar:
        task = bar.add_task("adversarial inputs", total=len(cases))
        for case in cases:
            records.append(_run_one(case))
            bar.advance(task)
    return records


def _by_group(records: list[Record]) -> dict[str, dict[str, int]]:
    groups: dict[str, Counter[str]] = {}
    for r in records:
        groups.setdefault(r.group, Counter())[r.outcome] += 1
    return {g: dict(sorted(c.items())) for g, c in groups.items()}


def _print(records: list[Record], summary: dict[str, Any]) -> None:
    for r in records:
        if r.outcome in BAD:
            print(f"{r.outcome:9} [{r.group}] {r.name}: {r.detail}")
    counts = summary["outcomes"]
    print(
        f"{summary['cases']} bad inputs tried, {counts.get('traceback', 0)} tracebacks, "
        f"{counts.get('hang', 0)} hangs, {counts.get('wrong', 0)} silent wrong results"
    )
    for group, c in summary["by_group"].items():
        print(f"  {group:7} " + ", ".join(f"{k} {v}" for k, v in c.items()))


if __name__ == "__main__":
    sys.exit(main())
