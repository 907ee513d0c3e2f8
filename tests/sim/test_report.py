"""The report from constructed records: JSON lines that read back equal, the table's rates and
failure counts, the bar chart's pixels, and the failure-picture hook."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from PIL import Image

from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord
from grace_dsl.sim.report import (
    ReportError,
    format_table,
    read_jsonl,
    save_failure_frames,
    summarize,
    summary_json,
    write_bar_chart,
    write_jsonl,
)


def rec(concept: str, task: str, seed: int, strict: bool, lenient: bool, reason: str = ""):  # type: ignore[no-untyped-def]
    return EpisodeRecord(
        config=EpisodeConfig(concept, task=task, scale=(0.5, 2.0)),  # type: ignore[arg-type]
        seed=seed,
        joint="slide",
        q_range=(0.0, 0.4),
        q_initial=0.1,
        q_final=0.35 if strict else 0.1,
        lenient=lenient,
        strict=strict,
        reason=reason,
        params={"width": 0.5},
        camera={"azimuth": 10.0, "elevation": 45.0},
    )


RECORDS = [
    rec("Drawer", "open", 1, True, True),
    rec("Drawer", "open", 2, True, True),
    rec("Drawer", "open", 3, False, True),  # moved, not far enough: a strict miss
    rec("Drawer", "open", 4, False, False, "slip"),
    rec("Drawer", "close", 5, True, True),
    rec("Drawer", "close", 6, False, False, "wrong_direction"),
    rec("SunkenDoor", "open", 7, False, False, "no_feasible_grasp"),
    rec("SunkenDoor", "close", 8, True, True),
]


def test_jsonl_round_trip(tmp_path: Path) -> None:
    path = write_jsonl(RECORDS, tmp_path / "run" / "episodes.jsonl")
    lines = path.read_text().splitlines()
    assert len(lines) == len(RECORDS)
    first = json.loads(lines[0])
    assert first["seed"] == 1 and first["config"]["concept"] == "Drawer"
    assert first["params"] == {"width": 0.5}
    assert read_jsonl(path) == RECORDS


def test_jsonl_refuses_a_line_that_is_no_record(tmp_path: Path) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text(json.dumps(RECORDS[0].to_json()) + '\n{"seed": 3}\n')
    with pytest.raises(ReportError, match="bad.jsonl:2: not an episode record"):
        read_jsonl(path)


def test_summary_rates_and_reasons() -> None:
    drawer, door = summarize(RECORDS)
    assert drawer.category == "Drawer" and door.category == "SunkenDoor"
    assert drawer.tasks["open"].episodes == 4
    assert drawer.tasks["open"].rate("lenient") == 0.75
    assert drawer.tasks["open"].rate("strict") == 0.5
    assert drawer.tasks["open"].reasons == {"": 1, "slip": 1}
    assert drawer.tasks["close"].rate("strict") == 0.5
    assert door.tasks["open"].rate("strict") == 0.0
    mean = summary_json([drawer, door])["mean"]
    assert mean["open"]["strict"] == pytest.approx(0.25)
    assert mean["close"]["strict"] == pytest.approx(0.75)


def test_table_has_both_criteria_side_by_side_per_task() -> None:
    text = format_table(summarize(RECORDS))
    header, _, drawer, door, _, mean = text.splitlines()
    assert header.split()[:7] == ["category", "open", "lenient", "open", "strict", "open", "n"]
    assert drawer.split()[:7] == ["Drawer", "0.75", "0.50", "4", "0.50", "0.50", "2"]
    assert "open:strict miss 1" in drawer and "open:slip 1" in drawer
    assert "close:wrong_direction 1" in drawer
    assert door.split()[:3] == ["SunkenDoor", "0.00", "0.00"]
    assert mean.split()[:5] == ["mean", "0.38", "0.25", "0.75", "0.75"]


def test_a_task_that_did_not_run_reads_as_a_dash() -> None:
    text = format_table(summarize(RECORDS[:4]))
    assert text.splitlines()[2].split()[4:7] == ["-", "-", "0"]


def test_bar_chart_is_a_real_picture(tmp_path: Path) -> None:
    path = write_bar_chart(summarize(RECORDS), tmp_path / "bars.png", "test run")
    img = Image.open(path).convert("RGB")
    assert img.width > 200 and img.height > 300
    colours = {c for _, c in img.getcolors(maxcolors=1 << 16) or []}
    assert (33, 113, 181) in colours and (217, 72, 1) in colours  # strict bars of both tasks
    # Drawer's open-strict bar (rate 0.5) is half the 300-pixel plot high
    column = [img.getpixel((60 + 12 + 14 + 3, y)) for y in range(img.height)]
    assert sum(c == (33, 113, 181) for c in column) == pytest.approx(150, abs=2)
    with pytest.raises(ReportError, match="no episodes"):
        write_bar_chart([], tmp_path / "none.png")


def test_failure_frames_hook_calls_the_renderer_for_failures_only(tmp_path: Path) -> None:
    seen = []

    def render(record: EpisodeRecord, path: Path) -> None:
        seen.append(record.seed)
        if record.seed == 6:
            raise RuntimeError("no GL context")
        Image.new("RGB", (4, 4), "red").save(path)

    written, skipped = save_failure_frames(RECORDS, tmp_path / "failures", render)
    assert seen == [3, 4, 6, 7]
    assert [p.name for p in written] == [
        "Drawer-open-gripper-3.png",
        "Drawer-open-gripper-4.png",
        "SunkenDoor-open-gripper-7.png",
    ]
    assert skipped == ["Drawer-close-gripper-6.png: RuntimeError: no GL context"]
