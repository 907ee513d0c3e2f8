"""``grace plan``: the summary and JSON agree with an independent look at the trajectory; the
pictures and the playable page are written; a user's mistakes are one line and exit code 1."""

from __future__ import annotations

import base64
import json
import re
import subprocess

import numpy as np
import pytest
from PIL import Image

from grace_dsl.cli.grace import main
from grace_dsl.robot.model import Robot
from tests.render.conftest import chromium, needs_chromium, needs_gl
from tests.robot.test_timing import differenced


@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """One CLI run with every output: its JSON and the files it wrote."""
    out = tmp_path_factory.mktemp("plan")
    files = {"html": out / "plan.html", "png": out / "plan.png"}
    return {"out": out, **files}


@pytest.mark.slow
def test_json_plan_is_consistent(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "SunkenDoor", "--to", "30deg", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["concept"] == "SunkenDoor" and data["joint"] == "hinge"
    assert data["to"] == pytest.approx(np.radians(30))
    traj = data["trajectory"]
    t, q, hinge = np.array(traj["t"]), np.array(traj["q"]), np.array(traj["object_joint"])
    robot = Robot.panda()
    assert np.all(np.diff(t) > 0) and t[-1] == pytest.approx(data["duration"])
    assert np.all(q >= robot.lower - 1e-6) and np.all(q <= robot.upper + 1e-6)
    vel, _ = differenced(q, t)
    assert np.all(np.abs(vel) <= robot.velocity_limit * 1.001)  # q rounded to 1e-6 in the JSON
    assert [p["phase"] for p in data["phases"]] == ["approach", "insert", "interact", "retreat"]
    starts = [p["start"] for p in data["phases"]]
    assert starts == sorted(starts) and starts[0] == 0.0
    assert hinge[0] == 0.0 and hinge[-1] == pytest.approx(np.radians(30), abs=1e-6)
    assert data["grasp"] in ("handle.pull", "handle.push", "push_edge")


@pytest.mark.slow
@pytest.mark.parametrize(
    "argv, message",
    [
        (["plan", "SunkenDor"], "SunkenDoor"),  # the suggestion
        (["plan", "SunkenDoor", "--action", "fly"], "no action 'fly'"),
        (["plan", "SunkenDoor", "--to", "far"], "--to"),
        (["plan", "SunkenDoor", "--base", "1,2"], "X,Y,YAW"),
        (["plan", "SunkenDoor", "--base", "3,0,0"], "no usable grasp"),  # far out of reach
        (["plan", "SunkenDoor", "--to", "3"], "range"),  # beyond the hinge's range
    ],
)
def test_mistakes_are_one_line(argv: list[str], message: str, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err


@pytest.mark.slow
@needs_gl
def test_png_and_playable_page(planned, capsys) -> None:  # type: ignore[no-untyped-def]
    argv = ["plan", "SunkenDoor", "--to", "0.5", "--png", str(planned["png"])]
    assert main([*argv, "--html", str(planned["html"])]) == 0
    text = capsys.readouterr().out
    assert "handle" in text or "push_edge" in text
    assert Image.open(planned["png"]).size == (1200, 900)
    page = planned["html"].read_text()
    m = re.search(r'<script type="application/json" id="scene-data">(.*?)</script>', page, re.S)
    assert m is not None
    data = json.loads(m.group(1))
    anim = data["animation"]
    times = np.frombuffer(base64.b64decode(anim["times"]), "<f4")
    values = np.frombuffer(base64.b64decode(anim["values"]), "<f4")
    assert len(times) == anim["frames"] > 10 and np.all(np.diff(times) > 0)
    assert values[0] == 0.0 and values.max() == pytest.approx(0.5, abs=1e-5)
    assert {t["part"] for t in anim["tracks"]} == set(range(len(data["parts"])))
    # The door leaf's track turns about the hinge axis by the hinge value (a rigid motion).
    leaf = next(i for i, p in enumerate(data["parts"]) if p["link"] == "leaf")
    poses = np.frombuffer(
        base64.b64decode(next(t for t in anim["tracks"] if t["part"] == leaf)["poses"]), "<f4"
    ).reshape(-1, 4, 4)
    k = int(np.argmax(values))
    angle = np.arccos(np.clip((np.trace(poses[k, :3, :3]) - 1) / 2, -1, 1))
    assert angle == pytest.approx(values[k], abs=1e-4)
    assert 'id="scrub"' in page and 'id="play"' in page


PROBE = """
<script>
window.addEventListener("error", function (e) {
  document.body.setAttribute("data-error", String(e.message));
});
setTimeout(function () {
  var c = document.getElementById("view"), s = document.getElementById("scrub");
  var first = c.toDataURL();
  s.value = s.max;
  s.dispatchEvent(new Event("input", { bubbles: true }));
  setTimeout(function () {
    document.body.setAttribute("data-changed", String(c.toDataURL() !== first));
  }, 300);
}, 300);
</script>
</body>"""


@pytest.mark.slow
@needs_gl
@needs_chromium
@pytest.mark.parametrize("fragment", ["", "#2d"])
def test_the_slider_moves_the_arm_in_chromium(planned, fragment, tmp_path) -> None:  # type: ignore[no-untyped-def]
    if not planned["html"].exists():
        assert main(["plan", "SunkenDoor", "--to", "0.5", "--html", str(planned["html"])]) == 0
    probe = tmp_path / "probe.html"
    probe.write_text(planned["html"].read_text().replace("</body>", PROBE), encoding="utf-8")
    dom = subprocess.run(
        [
            str(chromium()),
            "--headless",
            "--no-sandbox",
            "--window-size=640,480",
            "--virtual-time-budget=5000",
            "--dump-dom",
            probe.resolve().as_uri() + fragment,
        ],
        check=True,
        capture_output=True,
        text=True,
        timeout=180,
    ).stdout
    body = re.search(r"<body[^>]*>", dom)
    assert body is not None and "data-error" not in body.group(0), body.group(0) if body else dom
    last = re.search(r'id="scrub" type="range" min="0" max="(\d+)"', dom)
    assert last is not None
    assert f'data-frame="{last.group(1)}"' in body.group(0)
    assert 'data-changed="true"' in body.group(0)


@pytest.mark.slow
def test_the_default_target_is_as_far_as_the_placement_allows(capsys) -> None:  # type: ignore[no-untyped-def]
    """Without --to: 90% of the range, or (out of reach) just short of where the arm stopped."""
    from grace_dsl.cli.plan_cmd import DEFAULT_FRACTION

    assert main(["plan", "LidBox", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    hi = np.radians(110)  # LidBox's hinge range is [0, 110deg]
    assert 0.1 * hi < data["to"] <= DEFAULT_FRACTION * hi + 1e-9
    assert data["trajectory"]["object_joint"][-1] == pytest.approx(data["to"], abs=1e-6)
