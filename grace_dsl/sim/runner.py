"""Run many episodes: in this process, in a local process pool, or on a Ray cluster.

An episode is a pure function of ``(EpisodeConfig, seed)`` (``grace_dsl.sim.records``), so where
it runs does not change what it returns: results come back in the order they were asked for,
whatever the order they finish in. An episode that raises is not lost: it becomes a failure record
whose ``detail`` carries the exception and the last lines of its traceback.

Seeds: ``episode_seed(seed, category, task, index)`` is the documented rule that turns the bench's
``--seed`` into one seed per episode (a NumPy ``SeedSequence``), so a single episode of a large
run can be replayed alone from its record.
"""

from __future__ import annotations

import os
import sys
import traceback
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import replace
from multiprocessing import get_context
from typing import Any

import numpy as np

from grace_dsl.runtime.errors import GraceError, ParameterError
from grace_dsl.sim.records import FAILURE_REASONS, EpisodeConfig, EpisodeRecord, Task

EpisodeFn = Callable[[EpisodeConfig, int], EpisodeRecord]
Job = tuple[EpisodeConfig, int]
Advance = Callable[[int, EpisodeRecord], None]  # one more episode done: its index and record

#: The reason given to an episode whose own code raised; its detail starts with ``RAISED`` and
#: holds the exception and the last frames of its traceback.
CRASH_REASON = "error"
RAISED = "raised "
TASKS: tuple[Task, ...] = ("open", "close")


class RunnerError(GraceError):
    """The runner was asked for something it cannot do (a missing backend, a bad worker count)."""


def episode_seed(seed: int, category: str, task: str, index: int) -> int:
    """The seed of episode ``index`` of ``task`` on ``category`` in a run with ``--seed seed``.

    ``SeedSequence(entropy=seed, spawn_key=(crc32(category), crc32(task), index))``, its first
    32-bit word. CRC-32 of the UTF-8 names, not ``hash()``, which Python salts per process.
    Changing one episode's place in a run (more categories, more episodes) never changes another's
    seed, and 32 bits keep a seed short enough to type when replaying one episode.
    """
    if seed < 0 or index < 0:
        raise ParameterError(f"seed and index must be >= 0, got seed={seed} index={index}")
    key = (zlib.crc32(category.encode()), zlib.crc32(task.encode()), index)
    return int(np.random.SeedSequence(entropy=seed, spawn_key=key).generate_state(1)[0])


def plan_episodes(
    categories: Sequence[str],
    episodes: int,
    seed: int,
    base: EpisodeConfig | None = None,
    tasks: Sequence[Task] = TASKS,
) -> list[Job]:
    """Every (config, seed) of a bench run, category by category, then task, then index."""
    if episodes < 1:
        raise ParameterError(f"--episodes must be at least 1, got {episodes}")
    template = base or EpisodeConfig(concept="")
    return [
        (replace(template, concept=c, task=t), episode_seed(seed, c, t, i))
        for c in categories
        for t in tasks
        for i in range(episodes)
    ]


def run_episodes(
    configs_and_seeds: Iterable[Job],
    *,
    fn: EpisodeFn | None = None,
    workers: int = 1,
    ray_address: str | None = None,
    progress: bool = True,
    warm: bool | None = None,
    on_record: Callable[[int, EpisodeRecord], None] | None = None,
) -> list[EpisodeRecord]:
    """One record per ``(config, seed)``, in the order given.

    ``fn`` defaults to ``grace_dsl.sim.episode.run_episode``; another must be a module-level
    function (it is pickled by name for the pool and for Ray). ``workers`` 1 runs here, more runs
    a spawn-started process pool. ``ray_address`` (``"local"``: a new local Ray instance with
    ``workers`` CPUs; ``"auto"``: the running cluster; ``"ray://host:port"``) runs on Ray instead;
    if Ray is already initialised in this process, that instance is used as it is. ``warm``
    (default: only for the real episode) loads the compiled library once here and once in each
    worker process before any episode, so no episode pays for compiling or loading it.
    ``on_record(index, record)`` is called in this process as each episode finishes.
    """
    jobs = list(configs_and_seeds)
    if workers < 1:
        raise RunnerError(f"--workers must be at least 1, got {workers}")
    episode = fn if fn is not None else _default_fn()
    warm = fn is None if warm is None else warm
    if warm:
        _warm_once()  # builds the cache once, before workers race to build it
    with _progress_bar(len(jobs), progress) as bar:
        advance = _reporting(bar, on_record)
        if ray_address is not None:
            return _run_ray(jobs, episode, workers, ray_address, warm, advance)
        if workers == 1 or len(jobs) <= 1:
            out = []
            for i, (config, seed) in enumerate(jobs):
                out.append(guarded(episode, config, seed))
                advance(i, out[-1])
            return out
        return _run_pool(jobs, episode, workers, warm, advance)


def guarded(fn: EpisodeFn, config: EpisodeConfig, seed: int) -> EpisodeRecord:
    """``fn(config, seed)``, or a failure record saying what it raised or wrongly returned."""
    try:
        record = fn(config, seed)
    except Exception as exc:  # an episode's bug must cost one record, never the run
        return failure_record(config, seed, _reason_of(exc), RAISED + _summary(exc))
    if not isinstance(record, EpisodeRecord):
        got = type(record).__name__
        return failure_record(config, seed, CRASH_REASON, f"returned a {got}, not an EpisodeRecord")
    if record.reason not in FAILURE_REASONS:
        detail = f"unknown failure reason {record.reason!r}; {record.detail}"
        return replace(record, reason=CRASH_REASON, detail=detail, strict=False, lenient=False)
    return record


def failure_record(config: EpisodeConfig, seed: int, reason: str, detail: str) -> EpisodeRecord:
    """A record for an episode that produced none: no joint, no motion, not a success."""
    return EpisodeRecord(
        config=config,
        seed=seed,
        joint="",
        q_range=(0.0, 0.0),
        q_initial=0.0,
        q_final=0.0,
        lenient=False,
        strict=False,
        reason=reason,
        detail=detail,
    )


def _reason_of(exc: BaseException) -> str:
    """The vocabulary's word for an exception: a bad draw, an IK failure, or a crash."""
    if isinstance(exc, ParameterError):  # RequirementError among them
        return "invalid_draw"
    if "ik" in type(exc).__name__.lower().replace("_", ""):  # robot's IKError and kin
        return "ik_failure"
    if isinstance(exc, TimeoutError):
        return "timeout"
    return CRASH_REASON


def _summary(exc: BaseException, frames: int = 4) -> str:
    """``Type: message`` and the last ``frames`` frames as ``file:line in function``."""
    tb = traceback.extract_tb(exc.__traceback__)[-frames:]
    where = " <- ".join(f"{os.path.basename(f.filename)}:{f.lineno} in {f.name}" for f in tb[::-1])
    message = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {message} (at {where})" if where else f"{type(exc).__name__}"


def _default_fn() -> EpisodeFn:
    """The real episode, imported only when asked for (it needs MuJoCo)."""
    try:
        from grace_dsl.sim.episode import run_episode
    except ModuleNotFoundError as exc:
        if exc.name == "grace_dsl.sim.episode":
            raise RunnerError(
                "this grace_dsl has no simulated episode (grace_dsl.sim.episode)"
            ) from None
        raise RunnerError(
            f"the simulated episode needs {exc.name}: install the simulator with "
            "`pip install -e .[sim]`"
        ) from exc
    return run_episode


_LIBRARY: Any = None


def shared_library() -> Any:
    """The standard library, loaded once per process and kept.

    ``load_library`` parses and checks every source on each call (seconds) before it finds the
    compiled units in the cache; an episode that calls it would pay that every time. This is the
    per-process copy the workers warm and the bench's argument checks use.
    """
    global _LIBRARY
    if _LIBRARY is None:
        from grace_dsl.runtime.library import load_library

        _LIBRARY = load_library()
    return _LIBRARY


def _warm_once() -> None:
    """Load the compiled standard library once per process (compiling only if uncached)."""
    shared_library()


def _pool_task(fn: EpisodeFn, config: EpisodeConfig, seed: int, warm: bool) -> EpisodeRecord:
    if warm:
        _warm_once()
    return guarded(fn, config, seed)


def _run_pool(
    jobs: list[Job], fn: EpisodeFn, workers: int, warm: bool, advance: Advance
) -> list[EpisodeRecord]:
    """A spawn pool (no forked MuJoCo or GL state); a worker that dies costs its episodes."""
    out: list[EpisodeRecord | None] = [None] * len(jobs)
    init = _warm_once if warm else None
    context = get_context("spawn")
    pool = ProcessPoolExecutor(min(workers, len(jobs)), mp_context=context, initializer=init)
    try:
        futures: dict[Future[EpisodeRecord], int] = {
            pool.submit(_pool_task, fn, c, s, warm): i for i, (c, s) in enumerate(jobs)
        }
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                i = futures[future]
                out[i] = record = _collect(future, *jobs[i])
                advance(i, record)
    finally:  # on Ctrl-C, episodes not started are dropped rather than run to the end
        pool.shutdown(wait=True, cancel_futures=True)
    return [r for r in out if r is not None]


def _collect(future: Future[EpisodeRecord], config: EpisodeConfig, seed: int) -> EpisodeRecord:
    """A finished future's record; a dead worker or an unpicklable result as a failure."""
    try:
        return future.result()
    except BrokenProcessPool:
        return failure_record(
            config, seed, CRASH_REASON, RAISED + "a worker process died (a crash in native code?)"
        )
    except Exception as exc:
        return failure_record(config, seed, CRASH_REASON, RAISED + _summary(exc))


def _run_ray(
    jobs: list[Job],
    fn: EpisodeFn,
    workers: int,
    address: str,
    warm: bool,
    advance: Advance,
) -> list[EpisodeRecord]:
    """Each episode a Ray task of one CPU; results placed by index as they finish."""
    ray = _import_ray()
    started = not ray.is_initialized()
    if started:
        kwargs: dict[str, Any] = {"num_cpus": workers} if address == "local" else {}
        if not address.startswith("ray://"):  # this machine: its workers see this checkout
            path = os.pathsep.join(p for p in sys.path if p)
            kwargs["runtime_env"] = {"env_vars": {"PYTHONPATH": path}}
        try:
            ray.init(address=address, include_dashboard=False, log_to_driver=False, **kwargs)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise RunnerError(f"cannot start or reach Ray at {address!r}: {first}") from exc
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(_pool_task)
        refs = {task.remote(fn, c, s, warm): i for i, (c, s) in enumerate(jobs)}
        out: list[EpisodeRecord | None] = [None] * len(jobs)
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                i = refs[ref]
                try:
                    record = ray.get(ref)
                except Exception as exc:  # a dead worker, a lost node: RayError and kin
                    record = failure_record(*jobs[i], CRASH_REASON, RAISED + _summary(exc))
                out[i] = record
                advance(i, record)
        return [r for r in out if r is not None]
    finally:
        if started:
            ray.shutdown()


def _import_ray() -> Any:
    try:
        import ray
    except ImportError as exc:
        raise RunnerError("--ray needs Ray: install it with `pip install -e .[ray]`") from exc
    return ray


def _reporting(bar: Callable[[], None], on_record: Advance | None) -> Advance:
    """Advance the bar and hand each finished record to ``on_record`` (a log that an
    interrupted run keeps) as it comes, not when the last one does."""

    def advance(index: int, record: EpisodeRecord) -> None:
        if on_record is not None:
            on_record(index, record)
        bar()

    return advance


@contextmanager
def _progress_bar(total: int, enabled: bool) -> Iterator[Callable[[], None]]:
    """A rich bar on stderr (episodes done of ``total``, rate, time left); silent if disabled."""
    if not enabled or total == 0:
        yield lambda: None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = (
        TextColumn("episodes"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("episodes", total=total)
        yield lambda: bar.advance(task)
