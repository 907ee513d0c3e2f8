"""Render the gallery pictures of `StorageFurniture` (docs/gallery/storage_furniture_*.png).

Run from the repository root: ``.venv/bin/python docs/storage_furniture_gallery.py``. Each layout
is drawn by ``eacc show --png`` with its parameters and a few fronts opened, so a reader sees the
drawers' trays and the doors' hinge sides; four of them show the other handle types (knobs,
recessed pulls, bow handles) that ``handle_kind`` chooses.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "gallery"

# name -> (parameters, joints): the layouts the issue lists, each on a plinth or on legs
LAYOUTS: dict[str, tuple[dict[str, str], dict[str, str]]] = {
    "stack4": (
        {
            "rows": "4",
            "cols": "1",
            "doors": "0",
            "size": "600mm,900mm,480mm",
            "handle_kind": "knob",
        },
        {"drawer[1][0].slide": "250mm"},
    ),
    "row3": (
        {
            "rows": "1",
            "cols": "3",
            "doors": "0",
            "size": "1100mm,380mm,450mm",
            "stand": "legs",
            "tray_depth": "400mm",
        },
        {"drawer[0][1].slide": "250mm"},
    ),
    "grid2x2": (
        {
            "rows": "2",
            "cols": "2",
            "doors": "0",
            "size": "900mm,700mm,480mm",
            "handle_kind": "recessed",
        },
        {"drawer[0][0].slide": "200mm", "drawer[1][1].slide": "300mm"},
    ),
    "drawer_over_door": (
        {
            "rows": "1",
            "cols": "1",
            "doors": "1",
            "hinge_side": "right",
            "size": "600mm,720mm,560mm",
            "handle_kind": "knob",
        },
        {"door[0].hinge": "60deg", "drawer[0][0].slide": "150mm"},
    ),
    "two_drawers_over_two_doors": (
        {"rows": "1", "cols": "2", "doors": "2", "size": "900mm,800mm,560mm"},
        {"door[0].hinge": "50deg", "door[1].hinge": "80deg", "drawer[0][1].slide": "200mm"},
    ),
    "two_doors": (
        {
            "rows": "0",
            "doors": "2",
            "size": "800mm,900mm,500mm",
            "stand": "legs",
            "handle_kind": "curved",
        },
        {"door[1].hinge": "70deg"},
    ),
    "door_beside_blind": (
        {
            "rows": "0",
            "doors": "1",
            "blind": "1",
            "blind_side": "left",
            "blind_width": "350mm",
            "hinge_side": "left",
            "size": "900mm,720mm,560mm",
            "stand": "legs",
        },
        {"door[0].hinge": "70deg"},
    ),
    "drawer_over_door_beside_blind": (
        {
            "rows": "1",
            "cols": "1",
            "doors": "1",
            "blind": "1",
            "blind_side": "right",
            "blind_width": "300mm",
            "size": "1000mm,800mm,560mm",
        },
        {"door[0].hinge": "45deg"},
    ),
    "single_door": (
        {"rows": "0", "doors": "1", "hinge_side": "right", "size": "500mm,800mm,450mm"},
        {"door[0].hinge": "90deg"},
    ),
}


def render(name: str, params: dict[str, str], joints: dict[str, str]) -> Path:
    out = OUT / f"storage_furniture_{name}.png"
    cmd = [
        sys.executable,
        "-m",
        "grace_dsl.cli.eacc",
        "show",
        "StorageFurniture",
        "--png",
        str(out),
    ]
    cmd += [a for k, v in params.items() for a in ("--param", f"{k}={v}")]
    cmd += [a for k, v in joints.items() for a in ("--joint", f"{k}={v}")]
    cmd += ["--grasps", "0", "--size", "480x360"]
    subprocess.run(cmd, check=True, cwd=ROOT)
    return out


def main(argv: list[str] | None = None) -> int:
    """Render every layout, or only those named on the command line."""
    names = (sys.argv[1:] if argv is None else argv) or list(LAYOUTS)
    for name in names:
        params, joints = LAYOUTS[name]
        print(render(name, params, joints))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
