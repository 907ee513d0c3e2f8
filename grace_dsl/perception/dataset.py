"""A synthetic dataset on disk: views of several concepts, in shards, drawn in parallel.

Work is split into chunks of consecutive view indices; each chunk is a pure function of
(concept, dataset seed, first index, count, config), so the shards are byte-for-byte the same
arrays whatever the number of workers. Workers are forked from a parent that has loaded the
library, so they share its compiled code instead of loading it again.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.shards import write_shard
from grace_dsl.perception.types import ViewSample
from grace_dsl.perception.views import ViewConfig, check_config, generate_views
from grace_dsl.runtime.library import Library

CHUNK = 8  # views per task: small enough for a live progress bar, large enough to amortize

_LIBRARY: Library | None = None  # set in the parent before forking; workers inherit it


@dataclass(frozen=True)
class _Task:
    concept: str
    seed: int
    start: int
    count: int
    config: ViewConfig


def _run(task: _Task) -> list[ViewSample]:
    assert _LIBRARY is not None
    return generate_views(
        _LIBRARY[task.concept], task.count, task.seed, config=task.config, start=task.start
    )


def _tasks(concepts: Sequence[str], n: int, seed: int, config: ViewConfig) -> list[_Task]:
    return [
        _Task(c, seed, start, min(CHUNK, n - start), config)
        for c in concepts
        for start in range(0, n, CHUNK)
    ]


def generate_dataset(
    lib: Library,
    concepts: Sequence[str],
    n: int,
    out: str | Path,
    *,
    seed: int = 0,
    config: ViewConfig | None = None,
    workers: int = 1,
    shard_size: int = 256,
    progress: Callable[[int], None] | None = None,
) -> list[Path]:
    """Write ``n`` views of each concept to ``out/CONCEPT-KKKK.npz`` shards of ``shard_size``
    views; ``progress(k)`` is told as views are done. Returns the shard paths."""
    global _LIBRARY
    config = ViewConfig() if config is None else config
    check_config(config)
    for c in concepts:
        lib[c]  # an UnknownNameError names the concept before any work starts
    if n < 1 or shard_size < 1 or workers < 1:
        raise PerceptionError(
            f"n, shard_size and workers must be >= 1 (got {n}, {shard_size}, {workers})"
        )
    _LIBRARY = lib
    tasks = _tasks(concepts, n, seed, config)
    results: dict[tuple[str, int], list[ViewSample]] = {}
    if workers == 1:
        for t in tasks:
            results[(t.concept, t.start)] = _run(t)
            if progress:
                progress(t.count)
    else:
        ctx = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            futures: dict[Future[list[ViewSample]], _Task] = {
                pool.submit(_run, t): t for t in tasks
            }
            for f in as_completed(futures):
                t = futures[f]
                results[(t.concept, t.start)] = f.result()
                if progress:
                    progress(t.count)
    paths = []
    for c in concepts:
        views = [v for t in tasks if t.concept == c for v in results[(c, t.start)]]
        joints = lib[c].moving_joints
        for k in range(0, n, shard_size):
            path = Path(out) / f"{c}-{k // shard_size:04d}.npz"
            paths.append(write_shard(path, views[k : k + shard_size], joints, config))
    return paths
