"""The runner's contract: results in the order asked whatever the backend, an episode that raises
recorded as a failure, and the documented seed rule. The episode functions here are real, small,
pure, module-level functions (the pool and Ray pickle them by name), not a simulator stand-in."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from grace_dsl.runtime.errors import GraceError, RequirementError
from grace_dsl.sim.records import FAILURE_REASONS, EpisodeConfig, EpisodeRecord
from grace_dsl.sim.runner import (
    CRASH_REASON,
    RAISED,
    RunnerError,
    episode_seed,
    guarded,
    plan_episodes,
    run_episodes,
)


def toy_episode(config: EpisodeConfig, seed: int) -> EpisodeRecord:
    """A deterministic draw from the seed; episodes with seed % 3 == 0 finish last."""
    rng = np.random.default_rng(seed)
    q0 = float(rng.uniform(0.0, 0.2))
    time.sleep(0.05 if seed % 3 == 0 else 0.0)  # completion order differs from submission
    q1 = q0 + (0.3 if config.task == "open" else -q0)
    return EpisodeRecord(
        config=config,
        seed=seed,
        joint="slide",
        q_range=(0.0, 0.4),
        q_initial=q0,
        q_final=q1,
        lenient=True,
        strict=q1 >= 0.2 if config.task == "open" else q1 <= 0.02,
        detail=f"pid {os.getpid()}",
    )


def raising_episode(config: EpisodeConfig, seed: int) -> EpisodeRecord:
    if seed % 2:
        raise ZeroDivisionError("the controller divided by a zero mass")
    if config.task == "close":
        raise RequirementError("width must exceed 2 * wall")
    return toy_episode(config, seed)


def _strip_pid(records: list[EpisodeRecord]) -> list[dict[str, object]]:
    return [{**r.to_json(), "detail": ""} for r in records]


JOBS = [(EpisodeConfig("Drawer", task="open"), s) for s in range(6)] + [
    (EpisodeConfig("Drawer", task="close"), s) for s in range(6, 9)
]


def test_inline_keeps_order_and_is_deterministic() -> None:
    a = run_episodes(JOBS, fn=toy_episode, workers=1, progress=False)
    b = run_episodes(JOBS, fn=toy_episode, workers=1, progress=False)
    assert [(r.config.task, r.seed) for r in a] == [(c.task, s) for c, s in JOBS]
    assert _strip_pid(a) == _strip_pid(b)


def test_each_record_is_handed_over_as_it_finishes() -> None:
    """``on_record`` sees every record once, with its index, before the run returns (what a
    resumable log is written from)."""
    seen: list[tuple[int, EpisodeRecord]] = []
    out = run_episodes(
        JOBS,
        fn=raising_episode,
        workers=1,
        progress=False,
        on_record=lambda i, r: seen.append((i, r)),
    )
    assert [i for i, _ in seen] == list(range(len(JOBS)))
    assert [r for _, r in seen] == out


@pytest.mark.slow
def test_pool_of_two_matches_inline_in_order_raising_included() -> None:
    """One pool (spawning workers costs seconds): order, equality with inline, and raises."""
    inline = run_episodes(JOBS, fn=raising_episode, workers=1, progress=False)
    pooled = run_episodes(JOBS, fn=raising_episode, workers=2, progress=False)
    assert _strip_pid(pooled) == _strip_pid(inline)
    assert [r.seed for r in pooled] == [s for _, s in JOBS]
    assert [r.reason == "" for r in pooled[:6]] == [True, False] * 3
    assert all("ZeroDivisionError" in r.detail for r in pooled[1:6:2])
    succeeded = {r.detail for r in pooled if r.reason == ""}
    assert succeeded and f"pid {os.getpid()}" not in succeeded  # ran in other processes


def test_an_episode_that_raises_is_a_failure_record_not_lost() -> None:
    jobs = [(EpisodeConfig("Drawer", task="open"), 1), (EpisodeConfig("Drawer", "close"), 2)]
    crashed, bad_draw = run_episodes(jobs, fn=raising_episode, progress=False)
    assert crashed.reason == CRASH_REASON and crashed.reason in FAILURE_REASONS
    assert crashed.detail.startswith(RAISED + "ZeroDivisionError: the controller divided")
    assert "test_runner.py" in crashed.detail and "raising_episode" in crashed.detail
    assert not crashed.strict and not crashed.lenient and crashed.seed == 1
    assert bad_draw.reason == "invalid_draw" and "width must exceed" in bad_draw.detail


def test_a_wrong_return_and_an_unknown_reason_are_failures() -> None:
    wrong = guarded(lambda c, s: {"ok": True}, EpisodeConfig("Drawer"), 3)  # type: ignore[arg-type, return-value]
    assert wrong.reason == CRASH_REASON and "returned a dict" in wrong.detail
    odd = toy_episode(EpisodeConfig("Drawer"), 4)
    from dataclasses import replace

    fixed = guarded(lambda c, s: replace(odd, reason="gremlins"), EpisodeConfig("Drawer"), 4)
    assert fixed.reason == CRASH_REASON and "gremlins" in fixed.detail and not fixed.strict


def test_seed_rule_is_the_documented_seed_sequence() -> None:
    import zlib

    key = (zlib.crc32(b"Drawer"), zlib.crc32(b"open"), 7)
    expected = int(np.random.SeedSequence(entropy=11, spawn_key=key).generate_state(1)[0])
    assert episode_seed(11, "Drawer", "open", 7) == expected
    seeds = {
        episode_seed(11, c, t, i)
        for c in ("Drawer", "Oven")
        for t in ("open", "close")
        for i in range(50)
    }
    assert len(seeds) == 200  # distinct across categories, tasks and indices
    assert episode_seed(12, "Drawer", "open", 7) != expected
    assert all(0 <= s < 2**32 for s in seeds)
    with pytest.raises(GraceError, match="seed and index"):
        episode_seed(-1, "Drawer", "open", 0)


def test_plan_is_stable_when_the_run_grows() -> None:
    small = plan_episodes(["Drawer"], 2, seed=5)
    large = plan_episodes(["Oven", "Drawer"], 4, seed=5)
    assert [(c.concept, c.task) for c, _ in small] == [("Drawer", "open")] * 2 + [
        ("Drawer", "close")
    ] * 2
    assert set(small) <= set(large)  # adding categories or episodes keeps every earlier seed
    with pytest.raises(GraceError, match="at least 1"):
        plan_episodes(["Drawer"], 0, seed=5)


def test_bad_worker_count_is_a_typed_error() -> None:
    with pytest.raises(RunnerError, match="--workers"):
        run_episodes(JOBS, fn=toy_episode, workers=0)


@pytest.mark.slow
def test_ray_local_instance_runs_episodes_in_order() -> None:
    """Ray is a declared extra the Makefile installs: this runs, never skips."""
    import ray

    if not os.environ.get("RAY_ADDRESS"):  # no cluster to join: a typed error, not a traceback
        with pytest.raises(RunnerError, match="cannot start or reach Ray at 'auto'"):
            run_episodes(JOBS[:1], fn=toy_episode, ray_address="auto", progress=False)
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        jobs = JOBS[:2]
        records = run_episodes(jobs, fn=toy_episode, ray_address="local", progress=False)
        assert ray.is_initialized()  # the runner used the caller's instance and left it running
    finally:
        ray.shutdown()
    assert _strip_pid(records) == _strip_pid(run_episodes(jobs, fn=toy_episode, progress=False))
    assert all(r.detail != f"pid {os.getpid()}" for r in records)


@pytest.mark.slow
def test_ray_runs_real_episodes_on_two_local_workers() -> None:
    """A local Ray instance the runner starts (2 worker processes) runs the simulated episode:
    the same records as here, in the order asked, from processes other than this one."""
    jobs = plan_episodes(["CabinetDrawer"], 1, seed=0)
    here = run_episodes(jobs, workers=1, progress=False)
    on_ray = run_episodes(jobs, workers=2, ray_address="local", progress=False)
    assert [r.config.task for r in on_ray] == ["open", "close"]
    strip = [{**r.to_json(), "wall_seconds": 0.0} for r in on_ray]
    assert strip == [{**r.to_json(), "wall_seconds": 0.0} for r in here]
    assert all(not r.detail.startswith(RAISED) for r in on_ray), [r.detail for r in on_ray]
