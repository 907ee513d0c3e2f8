"""What a bench run leaves behind: its records as JSON lines, a table by category, a bar chart,
and a picture of each failure's last frame.

The table reads like the paper's articulated-object table turned on its side (one row per
category, as there are more categories than fit across a terminal): for each task the lenient and
the strict success rate side by side, then how many episodes ran and why the others failed. The
chart is drawn with Pillow (the simulator extra's dependency; the project has no plotting
library). Failure pictures need the scene renderer: ``save_failure_frames`` takes it as a callable
so this module stays free of MuJoCo.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from grace_dsl.runtime.errors import GraceError
from grace_dsl.sim.records import FAILURE_REASONS, EpisodeConfig, EpisodeRecord

TASKS = ("open", "close")
#: draws one failed episode's final frame to a PNG path (a replay from ``record.config`` and
#: ``record.seed``; the episode is a pure function of both, so the frame is the one it ended on)
FrameRenderer = Callable[[EpisodeRecord, Path], None]


class ReportError(GraceError):
    """A report cannot be read or written (a bad JSON-lines file, no Pillow for the chart)."""


@dataclass(frozen=True)
class TaskStats:
    """One task on one category: episodes, successes under both criteria, failure counts."""

    episodes: int = 0
    lenient: int = 0
    strict: int = 0
    reasons: dict[str, int] = field(default_factory=dict)

    def rate(self, criterion: str) -> float | None:
        """The success rate under ``"lenient"`` or ``"strict"``; None with no episode."""
        count = self.lenient if criterion == "lenient" else self.strict
        return count / self.episodes if self.episodes else None


@dataclass(frozen=True)
class CategoryRow:
    category: str
    tasks: dict[str, TaskStats]

    def to_json(self) -> dict[str, Any]:
        return {
            "category": self.category,
            **{
                task: {
                    "episodes": s.episodes,
                    "lenient": s.rate("lenient"),
                    "strict": s.rate("strict"),
                    "reasons": s.reasons,
                }
                for task, s in self.tasks.items()
            },
        }


# -- records as JSON lines ----------------------------------------------------------------------


def write_jsonl(records: Iterable[EpisodeRecord], path: Path) -> Path:
    """One JSON object per line and per episode, in run order; the file is replaced whole."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", encoding="utf-8") as f:
        for r in records:
            f.write(json.dumps(r.to_json(), sort_keys=True) + "\n")
    tmp.replace(path)
    return path


def read_jsonl(path: Path) -> list[EpisodeRecord]:
    """The records ``write_jsonl`` wrote, as values again (to re-report a run without rerunning)."""
    out = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            out.append(record_from_json(json.loads(line)))
        except (ValueError, TypeError, KeyError) as exc:
            raise ReportError(f"{path}:{n}: not an episode record ({exc})") from None
    return out


def record_from_json(d: dict[str, Any]) -> EpisodeRecord:
    config = dict(d["config"])
    config["scale"] = tuple(config.get("scale", (1.0, 1.0)))
    return EpisodeRecord(**{**d, "config": EpisodeConfig(**config), "q_range": tuple(d["q_range"])})


# -- the table ----------------------------------------------------------------------------------


def summarize(records: Iterable[EpisodeRecord]) -> list[CategoryRow]:
    """One row per category in order of first appearance; both tasks in every row."""
    counts: dict[str, dict[str, list[EpisodeRecord]]] = {}
    for r in records:
        counts.setdefault(r.config.concept, {t: [] for t in TASKS}).setdefault(
            r.config.task, []
        ).append(r)
    return [
        CategoryRow(category, {task: _stats(rs) for task, rs in by_task.items()})
        for category, by_task in counts.items()
    ]


def _stats(records: Sequence[EpisodeRecord]) -> TaskStats:
    reasons = Counter(r.reason for r in records if not r.strict)
    ordered = {k: reasons[k] for k in FAILURE_REASONS if reasons[k]}
    ordered.update({k: v for k, v in reasons.items() if k not in ordered})  # strict misses: ""
    return TaskStats(
        episodes=len(records),
        lenient=sum(r.lenient for r in records),
        strict=sum(r.strict for r in records),
        reasons=ordered,
    )


def mean_row(rows: Sequence[CategoryRow]) -> dict[str, dict[str, float | None]]:
    """The mean over categories of each task's rates (as the paper averages categories)."""
    out: dict[str, dict[str, float | None]] = {}
    for task in TASKS:
        out[task] = {}
        for criterion in ("lenient", "strict"):
            rates = [r for row in rows if (r := row.tasks[task].rate(criterion)) is not None]
            out[task][criterion] = sum(rates) / len(rates) if rates else None
    return out


def summary_json(rows: Sequence[CategoryRow]) -> dict[str, Any]:
    return {"categories": [r.to_json() for r in rows], "mean": mean_row(rows)}


def table_rows(rows: Sequence[CategoryRow]) -> tuple[list[str], list[list[str]]]:
    """Header and cells of the summary table: rates with two decimals, '-' where none ran.

    A failure count names the reason; ``strict miss`` is an episode that moved the joint the
    right way but not far enough (no failure reason, not strict)."""
    header = ["category"]
    for task in TASKS:
        header += [f"{task} lenient", f"{task} strict", f"{task} n"]
    header.append("failures")
    cells = []
    for row in rows:
        line = [row.category]
        for task in TASKS:
            s = row.tasks[task]
            line += [_rate(s.rate("lenient")), _rate(s.rate("strict")), str(s.episodes)]
        line.append(_failures(row))
        cells.append(line)
    mean = mean_row(rows)
    line = ["mean"]
    for task in TASKS:
        line += [_rate(mean[task]["lenient"]), _rate(mean[task]["strict"]), ""]
    cells.append([*line, ""])
    return header, cells


def format_table(rows: Sequence[CategoryRow]) -> str:
    """The summary table as aligned plain text (what ``grace bench`` prints and saves)."""
    header, cells = table_rows(rows)
    widths = [max(len(x) for x in col) for col in zip(header, *cells)]
    lines = [
        "  ".join(
            c.ljust(w) if i in (0, len(widths) - 1) else c.rjust(w)
            for i, (c, w) in enumerate(zip(line, widths))
        ).rstrip()
        for line in (header, *cells)
    ]
    lines.insert(1, "-" * len(lines[0]))
    lines.insert(len(lines) - 1, "-" * len(lines[0]))
    return "\n".join(lines)


def _rate(x: float | None) -> str:
    return "-" if x is None else f"{x:.2f}"


def _failures(row: CategoryRow) -> str:
    parts = []
    for task in TASKS:
        for reason, n in row.tasks[task].reasons.items():
            parts.append(f"{task}:{reason or 'strict miss'} {n}")
    return ", ".join(parts)


# -- the bar chart ------------------------------------------------------------------------------

_COLOURS = {
    ("open", "lenient"): (158, 202, 225),
    ("open", "strict"): (33, 113, 181),
    ("close", "lenient"): (253, 174, 107),
    ("close", "strict"): (217, 72, 1),
}


def write_bar_chart(rows: Sequence[CategoryRow], path: Path, title: str = "") -> Path:
    """Grouped bars per category: open and close, lenient (light) and strict (dark), 0 to 1."""
    try:
        from PIL import Image, ImageDraw
    except ImportError as exc:
        raise ReportError("the bar chart needs Pillow: `pip install -e .[sim]`") from exc
    if not rows:
        raise ReportError("no episodes to chart")
    group, bar, left, top, bottom, right = 4 * 14 + 24, 14, 60, 50, 120, 180
    width, height = left + group * len(rows) + right, top + 300 + bottom
    plot_h = 300
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    base = top + plot_h
    for tick in range(0, 11, 2):  # y axis with grid lines at 0, 0.2, ... 1
        y = base - plot_h * tick / 10
        draw.line([(left, y), (left + group * len(rows), y)], fill=(225, 225, 225))
        draw.text((left - 30, y - 6), f"{tick / 10:.1f}", fill="black")
    for i, row in enumerate(rows):
        x0 = left + i * group + 12
        for j, key in enumerate(_COLOURS):
            rate = row.tasks[key[0]].rate(key[1])
            if rate is None:
                continue
            x = x0 + j * bar
            draw.rectangle([(x, base - plot_h * rate), (x + bar - 2, base)], fill=_COLOURS[key])
        _vertical_label(img, row.category, (x0, base + 6))
    draw.line([(left, top), (left, base), (left + group * len(rows), base)], fill="black")
    for j, (task, criterion) in enumerate(_COLOURS):  # legend
        y = top + 18 * j
        lx = left + group * len(rows) + 20
        draw.rectangle([(lx, y), (lx + 12, y + 12)], fill=_COLOURS[(task, criterion)])
        draw.text((lx + 18, y), f"{task} {criterion}", fill="black")
    draw.text((left, 15), title or "success rate by category", fill="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)
    return path


def _vertical_label(img: Any, text: str, at: tuple[int, int]) -> None:
    """``text`` rotated to read bottom-up under its bars (long category names fit)."""
    from PIL import Image, ImageDraw

    label = Image.new("RGB", (8 * len(text) + 4, 14), "white")
    ImageDraw.Draw(label).text((2, 1), text, fill="black")
    img.paste(label.rotate(90, expand=True), at)


# -- failure pictures ---------------------------------------------------------------------------


def failure_frame_path(out: Path, record: EpisodeRecord) -> Path:
    c = record.config
    return out / f"{c.concept}-{c.task}-{c.agent}-{record.seed}.png"


def save_failure_frames(
    records: Iterable[EpisodeRecord], out: Path, render: FrameRenderer
) -> tuple[list[Path], list[str]]:
    """Call ``render(record, path)`` for every episode that is not a strict success.

    Returns the pictures written and, for each picture that could not be drawn, one line saying
    why: a picture explains a failure, so its own failure is reported, never raised over the run.
    """
    out.mkdir(parents=True, exist_ok=True)
    written, skipped = [], []
    for r in records:
        if r.strict:
            continue
        path = failure_frame_path(out, r)
        try:
            render(r, path)
        except Exception as exc:  # a renderer's error costs its picture only
            skipped.append(f"{path.name}: {type(exc).__name__}: {exc}")
            continue
        if path.is_file():
            written.append(path)
        else:
            skipped.append(f"{path.name}: the renderer wrote no file")
    return written, skipped
