"""The flying-gripper bench's episode seeds: ``--seed`` chooses a block of episodes of its own.

``--seed + i`` made ``--seed 1`` rerun episodes 1 ... of ``--seed 0``, so a second sample was
the first one shifted by one episode."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

from bench_sim import SEED_STRIDE, episode_seed, plan  # noqa: E402

from grace_dsl.sim.protocol import draw_episode  # noqa: E402


def test_seed_zero_keeps_the_recorded_episodes_and_other_seeds_share_none() -> None:
    zero = [s for _, s in plan(("Drawer",), 25, "panda", 0)]
    assert zero == [*range(25)] * 2  # open, then close: the seeds every recorded figure used
    one = {s for _, s in plan(("Drawer",), 25, "panda", 1)}
    two = {s for _, s in plan(("Drawer",), 25, "panda", 2)}
    assert not one & set(zero) and not one & two and len(one) == 25


def test_another_seed_draws_other_objects(lib) -> None:  # type: ignore[no-untyped-def]
    config, _ = plan(("Drawer",), 1, "panda", 0)[0]
    concept = lib["Drawer"]
    firsts = [draw_episode(config, concept, episode_seed(s, 0)) for s in (0, 1)]
    assert firsts[0].camera != firsts[1].camera and repr(firsts[0].params) != repr(firsts[1].params)


@pytest.mark.parametrize("seed, index", [(-1, 0), (0, -1), (0, SEED_STRIDE)])
def test_a_seed_or_index_out_of_range_is_refused(seed: int, index: int) -> None:
    with pytest.raises(ValueError, match="--seed"):
        episode_seed(seed, index)
