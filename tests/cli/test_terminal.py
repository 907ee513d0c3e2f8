"""User text reaches the terminal inert: control characters (ESC, OSC window titles, OSC-52
clipboard writes, bidi overrides) are escaped in ``explain``, ``list`` and diagnostics, rich
markup in doc strings prints literally (``[/]`` does not crash, ``[link=...]`` stays visible),
and a ``use`` through a symlink to a non-.eac file never echoes that file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from grace_dsl.cli.eacc import main
from grace_dsl.cli.output import clean

ROOT = Path(__file__).parents[2]
OSC = "\x1b]0;pwned\x07\x1b]52;c;ZXZpbA==\x07"
MARKUP = "[link=https://evil.example]click[/link] [/] [bold]x"


def _evil(tmp_path: Path) -> Path:
    path = tmp_path / "evil.eac"
    path.write_text(
        f"/// Evil {OSC} doc {MARKUP} \u202e\n"
        "concept Evil {\n"
        f'    param r : length in [1mm, 10mm] = 2mm "help {OSC} {MARKUP}"\n'
        "}\n"
    )
    return path


def _run(argv: list[str], terminal: bool) -> subprocess.CompletedProcess[str]:
    """``eacc`` in a subprocess; ``terminal`` makes rich draw as on a terminal (tables, styles)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "200"}
    env.pop("FORCE_COLOR", None)
    if terminal:
        env["FORCE_COLOR"] = "1"
    return subprocess.run(
        [sys.executable, "-m", "grace_dsl.cli.eacc", *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )


def test_clean_escapes_controls_but_keeps_text() -> None:
    assert clean(OSC) == "\\x1b]0;pwned\\x07\\x1b]52;c;ZXZpbA==\\x07"
    assert clean("a\tb\nc \u202e d \x9b") == "a\tb\nc \\u202e d \\x9b"
    assert clean("plain [/] text, ümlaut") == "plain [/] text, ümlaut"


@pytest.mark.slow
@pytest.mark.parametrize("terminal", [False, True])
def test_explain_and_list_print_doc_strings_inert(tmp_path: Path, terminal: bool) -> None:
    path = _evil(tmp_path)
    for argv in (["explain", "Evil", str(path)], ["list", str(path)]):
        proc = _run(argv, terminal)
        assert proc.returncode == 0, proc.stderr
        assert "MarkupError" not in proc.stderr and "Traceback" not in proc.stderr
        out = proc.stdout
        assert ("┃" in out) == terminal  # rich's table on a terminal, plain columns when piped
        assert "\x07" not in out and "\x1b]" not in out and "\u202e" not in out
        assert "\\x1b]0;pwned\\x07" in out.replace("\n", "").replace("│", "").replace(" ", "")
        if argv[0] == "explain":  # markup printed as written, not interpreted or dropped
            assert "[/]" in out and "[link=https://evil.example]click[/link]" in out
            assert "\x1b]8;" not in out  # no hidden hyperlink


def test_diagnostics_escape_source_text(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.eac"
    path.write_text(f"concept A {{\n    param r : length = 5 // {OSC}\n}}\n")
    assert main(["check", str(path)]) == 1
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\x07" not in err
    assert "\\x1b]52;c;ZXZpbA==\\x07" in err


def test_use_through_a_symlink_does_not_echo_the_target(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("root:x:0:0:root:/root:/bin/bash\n")
    (tmp_path / "passwd.eac").symlink_to(secret)
    main_file = tmp_path / "a.eac"
    main_file.write_text("use passwd.{X}\nconcept A {\n    param r : length = 2mm\n}\n")
    assert main(["check", str(main_file)]) == 1
    err = capsys.readouterr().err
    assert "root:x" not in err and "root" not in err.replace(str(tmp_path), "")
    assert "is a symlink to" in err and "not a .eac file" in err
    assert main(["check", "--json", str(main_file)]) == 1
    assert "root:x" not in capsys.readouterr().out
    # a directory scan skips the symlink instead of reading it
    assert main(["check", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "skipped" in err and "root:x" not in err


def test_explain_points_at_the_file_that_defines_a_concept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "mine.eac").write_text("concept MyThing {\n    param r : length = 2mm\n}\n")
    monkeypatch.chdir(tmp_path)
    assert main(["explain", "MyThing"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "mine.eac in this directory defines it: eacc explain MyThing mine.eac" in err
    assert main(["explain", "MyThing", "mine.eac"]) == 0
