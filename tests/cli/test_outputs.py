"""What the command line writes and reads besides sources: exports say what they overwrite,
replace (never follow) a symlink in the way and remove stale meshes from the directory they own;
``prompt -o`` into a directory it cannot write is one line; instance files nested 100,000 deep are
one line; FIFOs and symlink loops in a checked directory are skipped, not waited on; values take
the language's units."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grace_dsl.cli.eacc import main
from grace_dsl.cli.files import UserFileError, atomic_write
from grace_dsl.cli.units import UnitSyntaxError, quantities, quantity
from grace_dsl.compiler.types import format_si

ROOT = Path(__file__).parents[2]
CABINET = ROOT / "tests" / "export" / "cabinet.eac"
OK = "concept A {\n    param r : length = 2mm\n}\n"


# ---- exports ------------------------------------------------------------------------------------


def _export(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["export", "Cabinet", str(CABINET), *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_export_reports_overwrites_and_removes_its_stale_meshes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "c.urdf"
    first = _export(capsys, "--urdf", str(target))
    assert first["overwritten"] == [] and first["removed"] == []
    meshes = tmp_path / "c_meshes"
    assert {Path(m).name for m in first["meshes"]} == {p.name for p in meshes.iterdir()}
    (meshes / "old_link__gone.obj").write_text("o stale\n")  # left by another instance
    (meshes / "notes.txt").write_text("mine")  # not the export's: kept
    second = _export(capsys, "--urdf", str(target))
    assert str(target) in second["overwritten"]
    assert second["removed"] == [str(meshes / "old_link__gone.obj")]
    assert (meshes / "notes.txt").exists() and not (meshes / "old_link__gone.obj").exists()
    assert main(["export", "Cabinet", str(CABINET), "--urdf", str(target)]) == 0
    out = capsys.readouterr().out
    assert f"note: overwrote {target}" in out and "mesh file(s) in" in out
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging left


def test_export_replaces_a_symlink_instead_of_following_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    link = tmp_path / "c.stl"
    link.symlink_to(victim)
    assert main(["export", "Cabinet", str(CABINET), "--stl", str(link)]) == 0
    out = capsys.readouterr().out
    assert victim.read_text() == "precious\n"
    assert not link.is_symlink() and link.stat().st_size > 84
    assert f"replaced the symlink {link} (to {victim}) by a file" in out


def test_atomic_write_refuses_a_directory_and_keeps_nothing(tmp_path: Path) -> None:
    (tmp_path / "d.html").mkdir()
    with pytest.raises(UserFileError, match="is a directory"):
        atomic_write(tmp_path / "d.html", "x")
    assert [p.name for p in tmp_path.iterdir()] == ["d.html"]


def test_instance_json_nested_100000_deep_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000)
    argv = ["export", "Cabinet", str(CABINET), "--urdf", str(tmp_path / "c.urdf")]
    assert main([*argv, "--instance-json", str(deep)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nested too deeply" in err and "Traceback" not in err


def test_instance_json_that_is_a_fifo_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    os.mkfifo(tmp_path / "pipe.json")
    argv = ["export", "Cabinet", str(CABINET), "--urdf", str(tmp_path / "c.urdf")]
    assert main([*argv, "--instance-json", str(tmp_path / "pipe.json")]) == 1
    assert "a FIFO" in capsys.readouterr().err


# ---- prompt -o ----------------------------------------------------------------------------------


def _read_only_dir(tmp_path: Path) -> Path:
    """A directory this process cannot create files in: chmod 555, or /sys for root (who may
    write into a directory whatever its mode)."""
    if os.geteuid() == 0:
        return Path("/sys")
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o555)
    return out


def test_prompt_into_a_read_only_directory_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "a.eac").write_text(OK)
    out = _read_only_dir(tmp_path)
    before = sorted(p.name for p in out.iterdir())
    assert main(["prompt", str(tmp_path / "a.eac"), "-o", str(out / "c.md")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"eacc: cannot write {out / 'c.md'}: ") and err.count("\n") == 1
    assert sorted(p.name for p in out.iterdir()) == before


def test_prompt_output_is_written_whole(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "a.eac").write_text(OK)
    target = tmp_path / "out" / "catalog.md"
    assert main(["prompt", str(tmp_path / "a.eac"), "-o", str(target)]) == 0
    assert "A" in target.read_text()
    assert main(["prompt", str(tmp_path / "a.eac"), "-o", str(target)]) == 0
    assert f"overwrote {target}" in capsys.readouterr().err


# ---- check: what a directory holds --------------------------------------------------------------


def test_check_skips_a_fifo_and_a_symlink_loop(tmp_path: Path) -> None:
    (tmp_path / "a.eac").write_text(OK)
    os.mkfifo(tmp_path / "x.eac")
    (tmp_path / "loop.eac").symlink_to(tmp_path / "loop.eac")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "grace_dsl.cli.eacc", "check"]
    proc = subprocess.run(
        [*cmd, str(tmp_path)], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert "ok: 1 concept in 1 file" in proc.stdout
    assert "warning: skipped" in proc.stderr and "x.eac: a FIFO" in proc.stderr
    assert "loop.eac: a symlink loop" in proc.stderr and "Traceback" not in proc.stderr
    named = [str(tmp_path / "x.eac"), str(tmp_path / "loop.eac")]
    proc = subprocess.run([*cmd, *named], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 1
    assert "x.eac: a FIFO (named pipe), not a file" in proc.stderr  # not "no such file"
    assert "loop.eac: a symlink loop" in proc.stderr and "Traceback" not in proc.stderr


# ---- units --------------------------------------------------------------------------------------


def test_quantities_use_the_languages_units() -> None:
    assert quantity("45deg", "angle") == pytest.approx(math.pi / 4, abs=1e-15)
    assert quantity("600mm", "length") == pytest.approx(0.6, abs=1e-15)
    assert quantity("-2.5cm", "length") == pytest.approx(-0.025, abs=1e-15)
    assert quantity("0.3", "length") == 0.3  # a bare number is SI
    assert quantities("(600mm, 400mm 20 mm)", "length") == pytest.approx([0.6, 0.4, 0.02])
    for bad, dim, message in [
        ("45mm", "angle", "is a length, expected an angle"),
        ("2deg", "length", "is an angle, expected a length"),
        ("3ft", "length", "unknown unit 'ft'"),
        ("__import__('os')", "length", "is not a number"),
        ("1e999", None, "not a finite number"),
        ("nan", None, "is not a number"),
    ]:
        with pytest.raises(UnitSyntaxError, match=message.replace("(", r"\(")):
            quantity(bad, dim)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e3, 1e3, allow_nan=False), st.sampled_from(["length", "angle"]))
def test_quantity_reads_what_format_si_prints(value: float, dim: str) -> None:
    """Round trip through the way eacc prints values (mm, deg with 6 significant digits)."""
    text = format_si(value, dim)
    assert quantity(text, dim) == pytest.approx(value, rel=1e-5, abs=1e-9)


def test_export_with_units_equals_export_in_si(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from grace_dsl.cli.instance_args import joint_values, parse_pose

    assert joint_values(
        {"hinge": "30deg", "slide": "120mm"}, {"hinge": "revolute", "slide": "prismatic"}
    ) == pytest.approx({"hinge": math.pi / 6, "slide": 0.12})
    np.testing.assert_allclose(
        parse_pose("1m,0,900mm,0,0,90deg"), parse_pose(f"1,0,0.9,0,0,{math.pi / 2!r}"), atol=1e-15
    )
    si = _export(
        capsys,
        "--mjcf",
        str(tmp_path / "si.xml"),
        "--param",
        "size=0.5,0.4,0.3",
        "--joint",
        "hinge=0.5235987755982988",
        "--joint",
        "slide=0.12",
    )
    units = _export(
        capsys,
        "--mjcf",
        str(tmp_path / "units.xml"),
        "--param",
        "size=500mm,400mm,300mm",
        "--joint",
        "hinge=30deg",
        "--joint",
        "slide=120mm",
    )
    assert units["joints"] == si["joints"] and units["masses"] == si["masses"]
    assert (
        main(
            [
                "export",
                "Cabinet",
                str(CABINET),
                "--urdf",
                str(tmp_path / "x.urdf"),
                "--joint",
                "hinge=30mm",
            ]
        )
        == 1
    )
    err = capsys.readouterr().err
    assert "joint hinge takes a number (rad, or 45deg): '30mm' is a length" in err


def test_the_compiler_api_skips_what_the_cli_skips(tmp_path: Path) -> None:
    """``compile_paths(DIR)`` (no command line in between) neither blocks on a FIFO, nor fails
    on a symlink loop, nor reads a symlink to a file that is not .eac."""
    (tmp_path / "a.eac").write_text(OK)
    os.mkfifo(tmp_path / "x.eac")
    (tmp_path / "loop.eac").symlink_to(tmp_path / "loop.eac")
    secret = tmp_path / "secret.txt"
    secret.write_text("root:x:0:0\n")
    (tmp_path / "passwd.eac").symlink_to(secret)
    script = (
        "import sys\nfrom grace_dsl.compiler.resolve import resolve\n"
        f"prog, diags = resolve([{str(tmp_path)!r}])\n"
        "print(sorted(prog.files), [d.message for d in diags])\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert "a.eac" in proc.stdout and "root:x" not in proc.stdout
    assert "x.eac" not in proc.stdout and "loop.eac" not in proc.stdout
