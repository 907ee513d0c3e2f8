"""The `eacc` command line: exit codes, JSON output, and the files it writes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from grace_dsl.cli.eacc import main
from grace_dsl.compiler.resolve import stdlib_dir
from tests.conftest import write

BAD = "use primitives.{Cuboid}\nconcept A {\n    param r : length = 5\n    let x = r + 1deg\n}\n"


def test_check_clean_library_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(stdlib_dir())]) == 0
    assert "ok: " in capsys.readouterr().out


def test_check_reports_every_error_and_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, "bad.eac", BAD)
    assert main(["check", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:24: error[E204]" in err and f"{path}:4:13: error[E203]" in err
    assert "2 errors" in err and "Traceback" not in err


def test_check_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "bad.eac", BAD)
    assert main(["check", "--json", str(path)]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["ok"] is False
    assert [(d["code"], d["line"], d["col"]) for d in data["diagnostics"]] == [
        ("E204", 3, 24),
        ("E203", 4, 13),
    ]


@pytest.mark.slow
def test_usage_errors_exit_2() -> None:
    for argv in (["frobnicate"], ["check"], []):
        proc = subprocess.run(
            [sys.executable, "-m", "grace_dsl.cli.eacc", *argv], capture_output=True, text=True
        )
        assert proc.returncode == 2, argv


def test_missing_file_is_a_diagnostic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(tmp_path / "nope.eac")]) == 1
    assert "E006" in capsys.readouterr().err


def test_build_writes_an_artifact(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "art"
    assert main(["build", str(stdlib_dir()), "-o", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] and report["output"] == str(out)
    manifest = json.loads((out / "manifest.json").read_text())
    assert "SunkenDoor" in manifest["concepts"]
    assert {u["key"] for u in report["units"]} == set(manifest["units"])


def test_list_and_explain_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list", "--json"]) == 0
    names = {c["name"] for c in json.loads(capsys.readouterr().out)}
    assert {"CurveHandle", "SunkenDoor", "Ring"} <= names
    assert main(["explain", "CurveHandle", "--json"]) == 0
    entry = json.loads(capsys.readouterr().out)
    grasp = next(g for g in entry["grasps"] if g["name"] == "pull")
    assert grasp["source"] == (
        "rotz(theta) * trans(0, -r_out, 0) * rpy(90deg, 0, 90deg) * roty(90deg)"
    )
    assert "sin(theta)" in grasp["formula"]["text"]


def test_explain_text_and_unknown_concept(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["explain", "SunkenDoor"]) == 0
    out = capsys.readouterr().out
    assert "handle.r_out" in out and "hinge" in out and "open" in out
    assert main(["explain", "SunkenDor"]) == 1
    assert "did you mean 'SunkenDoor'" in capsys.readouterr().err


def test_fmt_check_and_rewrite(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "messy.eac", "concept   A {param r:length=2mm   // keep me\n}\n")
    assert main(["fmt", "--check", str(path)]) == 1
    assert main(["fmt", str(path)]) == 0
    formatted = path.read_text()
    assert "// keep me" in formatted and "param r : length = 2mm" in formatted
    assert main(["fmt", "--check", str(path)]) == 0


def test_grace_demo_ranks_and_draws(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The demo a new user runs first: the door's grasp, force and path, the manipulation
    functions two hands would use (a hand that cannot close pushes the door shut), and a
    viewer page (the PNG is checked by tests/render)."""
    from grace_dsl.cli.grace import main as grace_main

    assert grace_main(["demo", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "force to open:" in out
    after = out.split("to close with a hand that cannot close:")[1]
    assert after.splitlines()[1].split()[-1] == "yes"  # its best option is a push
    assert "by push" in after.splitlines()[1]
    html = (tmp_path / "SunkenDoor.html").read_text()
    assert "<script" in html and "SunkenDoor" in html
