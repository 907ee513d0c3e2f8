"""``eacc fmt`` never destroys a source file, and every file problem is one line, not a
traceback: a file-size limit (the full-disk failure), invalid UTF-8, a missing file, a dangling
symlink, a read-only file, a directory named ``*.eac``, a FIFO, a symlink loop."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from grace_dsl.cli.eacc import main
from grace_dsl.lang.formatter import check_formatted
from grace_dsl.lang.parser import parse

ROOT = Path(__file__).parents[2]

MESSY = "concept   A {param r:length=2mm   // keep me\n}\n"


def _messy_big(n: int = 120) -> str:
    """A valid file of several KB that needs formatting (every line misaligned)."""
    params = "".join(f"  param p{i}:length   =  {i + 1}mm  // note {i}\n" for i in range(n))
    return f"concept   Big {{\n{params}}}\n"


def _one_line_error(err: str, *needles: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines and all(line.startswith("eacc: ") for line in lines), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, (needle, err)


def test_fmt_under_a_file_size_limit_leaves_the_original_whole(tmp_path: Path) -> None:
    """The issue's failure: under RLIMIT_FSIZE a 4,889-byte file was cut to 2,048 bytes. Now
    the write fails on the temporary file and the original keeps every byte."""
    path = tmp_path / "big.eac"
    path.write_text(_messy_big())
    before = path.read_bytes()
    assert len(before) > 4096
    script = textwrap.dedent(
        f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_FSIZE, (2048, 2048))
        from grace_dsl.cli.eacc import main
        sys.exit(main(["fmt", {str(path)!r}]))
        """
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 1, proc.stderr
    _one_line_error(proc.stderr, "cannot write", "big.eac")
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.eac"]  # no temporary left


def test_fmt_rewrites_when_it_can(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "big.eac"
    path.write_text(_messy_big())
    path.chmod(0o640)
    old = parse(path.read_text())
    assert main(["fmt", str(path)]) == 0
    new_text = path.read_text()
    assert check_formatted(new_text) and "// note 119" in new_text
    assert parse(new_text).module.concepts == old.module.concepts  # type: ignore[union-attr]
    assert path.stat().st_mode & 0o777 == 0o640  # the file's permissions are kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.eac"]


def test_fmt_accepts_and_keeps_a_byte_order_mark(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bom.eac"
    path.write_bytes(b"\xef\xbb\xbf" + MESSY.encode())
    assert main(["check", str(path)]) == 0  # the compiler accepts it ...
    assert main(["fmt", str(path)]) == 0  # ... and so does fmt
    data = path.read_bytes()
    assert data.startswith(b"\xef\xbb\xbf") and check_formatted(data[3:].decode())
    assert main(["fmt", "--check", str(path)]) == 0


def test_fmt_invalid_utf8_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "latin1.eac"
    path.write_bytes("concept A {} // caf\xe9\n".encode("latin-1"))
    assert main(["fmt", str(path)]) == 1
    _one_line_error(capsys.readouterr().err, "not UTF-8 text: byte 0xe9 at line 1, column 20")


def test_fmt_missing_file_and_dangling_symlink(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["fmt", str(tmp_path / "nope.eac")]) == 1
    _one_line_error(capsys.readouterr().err, "nope.eac: no such file")
    link = tmp_path / "dangling.eac"
    link.symlink_to(tmp_path / "gone.eac")
    assert main(["fmt", str(link)]) == 1
    _one_line_error(capsys.readouterr().err, "dangling.eac: a dangling symlink")


def test_fmt_leaves_a_read_only_file_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "ro.eac"
    path.write_text(MESSY)
    path.chmod(0o444)
    assert main(["fmt", str(path)]) == 1
    _one_line_error(capsys.readouterr().err, "ro.eac: the file is read-only")
    assert path.read_text() == MESSY


def test_fmt_through_a_symlink_rewrites_the_file_it_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    real = tmp_path / "real.eac"
    real.write_text(MESSY)
    link = tmp_path / "link.eac"
    link.symlink_to(real)
    assert main(["fmt", str(link)]) == 0
    assert link.is_symlink() and check_formatted(real.read_text())


def test_fmt_directory_with_a_dir_named_eac_a_fifo_and_a_loop(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A directory named x.eac is searched, not read; a FIFO is skipped with a warning instead
    of blocking (the test runs in a subprocess with a timeout); a symlink loop is skipped."""
    (tmp_path / "sub.eac").mkdir()
    (tmp_path / "sub.eac" / "inner.eac").write_text(MESSY)
    os.mkfifo(tmp_path / "pipe.eac")
    (tmp_path / "loop.eac").symlink_to(tmp_path / "loop.eac")
    proc = subprocess.run(
        [sys.executable, "-m", "grace_dsl.cli.eacc", "fmt", str(tmp_path)],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "warning: skipped" in proc.stderr and "pipe.eac: a FIFO" in proc.stderr
    assert "loop.eac: a symlink loop" in proc.stderr
    assert check_formatted((tmp_path / "sub.eac" / "inner.eac").read_text())


def test_fmt_named_fifo_and_loop_are_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    os.mkfifo(tmp_path / "pipe.eac")
    (tmp_path / "loop.eac").symlink_to(tmp_path / "loop.eac")
    assert main(["fmt", str(tmp_path / "pipe.eac"), str(tmp_path / "loop.eac")]) == 1
    _one_line_error(capsys.readouterr().err, "pipe.eac: a FIFO", "loop.eac: a symlink loop")


def test_fmt_refuses_output_that_does_not_read_back(tmp_path: Path) -> None:
    """The check before the rename: a written file that is not the same program is refused and
    the original stays (here the check is handed a different program)."""
    from grace_dsl.cli.files import UserFileError, atomic_write
    from grace_dsl.cli.fmt_cmd import _program, _same_program

    path = tmp_path / "a.eac"
    path.write_text(MESSY)
    other = _program("concept B {}\n", "b.eac")
    with pytest.raises(UserFileError, match="does not read back as the same program"):
        atomic_write(path, "concept A {}\n", verify=lambda t: _same_program(t, other, path))
    assert path.read_text() == MESSY
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.eac"]
