"""The ``estimated`` mode: the agent's model of an object from the simulated RGB-D camera.

Real parts throughout: MuJoCo renders the view, the renderer's labels segment it, ``eac.estimate``
(with the shipped network's start) fits the concept, and the flying hand acts in MuJoCo."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.agent.estimated import (
    MIN_CONFIDENCE,
    EstimateRefused,
    Estimator,
    View,
    camera_for,
    frame_of,
    look,
    object_cloud,
    object_shot,
    perceive,
    render_from,
)
from grace_dsl.agent.execute import Executor
from grace_dsl.agent.plan import Condition, Plan, SceneObject, SceneSpec, SubTask, Target
from grace_dsl.perception.views import split_params
from grace_dsl.sim.scene import Scene

pytestmark = pytest.mark.slow  # every test renders and fits (seconds each)


def _standing(lib: eac.Library, name: str) -> tuple[Scene, object, object]:
    """The concept's default instance standing on the floor, its front facing world +x."""
    scene = Scene.from_instances([lib[name].instantiate()], yaw=[math.pi / 2])
    model, data = scene.compile()
    return scene, model, data


def test_one_view_of_a_handle_gives_its_parameters_and_pose(lib: eac.Library) -> None:
    scene, model, data = _standing(lib, "StraightHandle")
    true = scene.instances[0]
    centre, radius = frame_of(true)
    got = look(scene, model, data, 0, lib["StraightHandle"], View(10, 40), centre, radius, seed=0)
    truth, _ = split_params(lib["StraightHandle"], true.params)
    est, _ = split_params(lib["StraightHandle"], got.params)
    assert got.confidence >= MIN_CONFIDENCE and got.points > 500
    assert max(abs(est[k] - v) for k, v in truth.items()) < 0.006  # every length within 6 mm
    assert np.linalg.norm(got.pose[:3, 3] - true.pose[:3, 3]) < 0.01  # its world pose too
    assert got.pose[:3, 2] @ true.pose[:3, 2] > math.cos(math.radians(10))


def test_a_cloud_of_another_object_is_refused(lib: eac.Library) -> None:
    scene, model, data = _standing(lib, "Microwave")
    centre, radius = frame_of(scene.instances[0])
    frame, geoms = render_from(scene, model, data, camera_for(View(10, 40), centre, radius))
    shot = object_shot(frame, scene, model, 0, geoms)
    points, _ = object_cloud(shot, frame.rgb, "Microwave", seed=0)
    with pytest.raises(EstimateRefused) as refused:  # a microwave is no bar handle
        perceive(lib["StraightHandle"], points, shot.camera_pose, View(10, 40))
    assert refused.value.perceived is not None
    assert refused.value.perceived.confidence < MIN_CONFIDENCE
    assert "take another view" in str(refused.value)


def test_a_view_of_the_back_is_refused(lib: eac.Library) -> None:
    """No handle pixels from behind: the agent does not act on a guess of where it is."""
    scene, model, data = _standing(lib, "CabinetDrawer")
    centre, radius = frame_of(scene.instances[0])
    with pytest.raises(EstimateRefused, match="pixels of its handle are in view"):
        look(scene, model, data, 0, lib["CabinetDrawer"], View(180, 40), centre, radius)


MICROWAVE = SceneSpec(
    "one microwave", (SceneObject("microwave", "Microwave", {"size": (0.5, 0.3, 0.4)}),)
)
OPEN = SubTask(
    "open the microwave", "microwave", "Microwave", "door", "open", "hinge",
    Target("open"), Condition("microwave", "hinge", 0.873, 1.745),
)  # fmt: skip


def test_a_retry_looks_again_from_the_next_view(lib: eac.Library) -> None:
    """The first view is from behind (refused: the handle is not in view), so the first
    attempt does not act; the retry re-estimates from the front, fits both looks together
    (nothing moved the microwave in between) and acts on that estimate."""
    estimator = Estimator(views=((180.0, 40.0), (10.0, 40.0)))
    executor = Executor(MICROWAVE, lib, params=estimator, max_attempts=2, seconds=2.0)
    step = executor.run(Plan("open the microwave", (), (OPEN,))).steps[0]
    first, second = step.attempts
    assert first.reason == "low_confidence" and first.option == "" and first.q_after == 0.0
    assert "handle" in first.detail
    assert second.estimate["view"][0] == 10.0 and second.estimate["confidence"] >= 0.5
    assert second.option  # it acted on the new estimate
    assert [a["view"][0] for a in estimator.account if "fused" not in a] == [180.0, 10.0]
    assert [a.get("fused") for a in estimator.account] == [None, None, 2]  # both looks fitted
    assert second.estimate.get("fused") == 2 or "refused" in estimator.account[-1]


def test_grace_run_estimated_completes_a_step(
    lib: eac.Library, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from grace_dsl.cli.grace import main

    monkeypatch.setattr("grace_dsl.runtime.library.load_library", lambda: lib)
    argv = ["run", "open the microwave", "--scene", "kitchen", "--mode", "estimated",
            "--attempts", "1", "--seconds", "1", "--json"]  # fmt: skip
    code = main(argv)
    out = json.loads(capsys.readouterr().out)
    assert code in (0, 3)  # verified or not, the step ran
    (attempt,) = out["steps"][0]["attempts"]
    assert attempt["estimate"]["source"] == "learned+fit"  # Microwave has shipped weights
    assert attempt["reason"] in ("", "low_confidence", "slip", "timeout", "collision")


def test_a_true_estimate_reproduces_the_oracle_episode(monkeypatch: pytest.MonkeyPatch) -> None:
    """The control: given the truth as its estimate, the estimated episode succeeds as the
    oracle's (the same world, hand, grasp and path), so what estimated mode loses is
    perception's error alone. Its open goes further: not knowing whether its travel is right,
    the agent follows a drawer past the estimated range until it stops (``beyond``), where the
    oracle stops at 90 % of the range it knows."""
    from grace_dsl.agent import estimated_episode as ee
    from grace_dsl.agent.estimated import Perceived
    from grace_dsl.sim.episode import run_episode
    from grace_dsl.sim.records import EpisodeConfig

    def truth(true, first, seed, min_confidence, looks, hold, fused):  # type: ignore[no-untyped-def]
        got = Perceived(true.concept.name, dict(true.params), true.pose, dict(true.joints),
                        0.0, 1.0, "truth", first, 0, 0.0)  # fmt: skip
        return got, [got.summary()]

    monkeypatch.setattr(ee, "perceive_episode", truth)
    config = EpisodeConfig("CabinetDrawer", "open", mode="estimated")
    estimated = ee.run_estimated_episode(config, 3)
    oracle = run_episode(EpisodeConfig("CabinetDrawer", "open"), 3)
    assert estimated.strict == oracle.strict and estimated.option == oracle.option
    assert estimated.q_final >= oracle.q_final - 2e-3  # on to the drawer's stop, not short
    assert estimated.estimate["pose_error_mm"] == 0.0
    assert estimated.estimate["length_error_max_mm"] == 0.0
