"""Does ``rank`` agree with an independent geometric physics check, for every concept and hand?

Run: ``.venv/bin/python bench/bench_rank_agreement.py [--concepts NAME ...] [--hands NAME ...]
[--out FILE] [--smoke] [--merge JSON ...]``. For every library concept, at two poses (front facing
the robot, front facing up), every action and every shipped hand, ``inst.rank`` judges each
manipulation function.
Each option is then checked again here, with code that shares nothing with the ranker's geometry:

- **geometry**: the hand's boxes, sampled on their surfaces every ``SPACING``, at ``APPROACH_STEP``
  steps along the whole approach (the hand backed off along the contact's -z to the grasp, a
  pinch's fingers open by the ranker's clearance, then closing in 1 mm steps) and at
  ``PATH_STEPS`` joint values along the follow path of a joint action (the instance rebuilt with
  ``with_joints`` at each and queried through the public ``inst.sdf``): no point deeper than
  ``DEPTH`` inside the part;
- **force**: the action's force at the grasp lies in the mode's transmissible set (a pinch: any;
  a hook: towards its +x wall and not in along its approach; a push: within 60 deg of its +z); a
  twist needs a hand that turns;
- **orientation**: the hand within its cones at the grasp, and for a pinch along the whole path;
  a hand that cannot turn turned by at most 5 deg along it.

A feasible option agrees when it passes; a rejected one must carry a reason, and agrees when
the check also fails at the pose the ranker reports. Prints the table by hand and writes
bench/results/rank_agreement.json (every disagreement listed). ``--smoke``: three concepts, one
pose. ``--merge``: one table from runs over parts of the library (each ``--concepts`` a shard, so
that the parts run side by side). Exits 1 when a feasible option fails the check.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.verify import verifiable

RESULTS = Path(__file__).resolve().parent / "results" / "rank_agreement.json"
SMOKE = ("CabinetDrawer", "RotaryDial", "SunkenDoor")
SPACING = 0.004  # m between sample points on every box face
APPROACH_STEP = 0.005  # m between hand positions along the approach
PATH_STEPS = 12
DEPTH = 0.002  # m a box may sink into the part (the ranker's and eacc verify's tolerance)
TIE = 1e-9  # m: a depth equal to DEPTH up to rounding is at the limit, not beyond it
CLEARANCE = 0.01  # m a pinch opens beyond its width on each side (the ranker's)
CONE = math.radians(60.0)
TURN = math.radians(5.0)


def facing() -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]])
    m[:3, 3] = (1.0, 0.0, 0.8)
    return m


def face_up() -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (0.6, 0.0, 0.4)
    return m


POSES = {"facing": facing, "up": face_up}


# ---- the independent check ----------------------------------------------------------------------


def box_points(center: np.ndarray, rot: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Surface points of a box (hand frame), a grid every SPACING on each face."""
    out = []
    for axis in range(3):
        a, b = [i for i in range(3) if i != axis]
        ua = np.linspace(-half[a], half[a], max(2, int(math.ceil(2 * half[a] / SPACING)) + 1))
        ub = np.linspace(-half[b], half[b], max(2, int(math.ceil(2 * half[b] / SPACING)) + 1))
        ga, gb = np.meshgrid(ua, ub)
        for sign in (-1.0, 1.0):
            p = np.zeros((ga.size, 3))
            p[:, axis] = sign * half[axis]
            p[:, a], p[:, b] = ga.ravel(), gb.ravel()
            out.append(p)
    return np.concatenate(out) @ rot.T + center


def rpy(r: float, p: float, y: float) -> np.ndarray:
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def hand_points(hand: Gripper, width: float, fingers_only: bool = False) -> np.ndarray:
    """The whole hand at opening ``width`` (hand frame), built from the description's numbers."""
    pts = []
    t, w, length = hand.finger_thickness, hand.finger_width, hand.finger_length
    half = np.array([w / 2, t / 2, length / 2])
    for side in (-1.0, 1.0):
        pts.append(
            box_points(np.array([0, side * (width / 2 + t / 2), -length / 2]), np.eye(3), half)
        )
        for b in hand.fingers:
            c = np.array(b.center) + np.array([0, width / 2, 0])
            r = rpy(*b.rpy)
            if side < 0:  # mirror through y = 0
                c, r = c * [1, -1, 1], np.diag([1, -1, 1]) @ r @ np.diag([1, -1, 1])
            pts.append(box_points(c, r, np.array(b.half_extents)))
    if not fingers_only:
        for b in hand.palm:
            pts.append(box_points(np.array(b.center), rpy(*b.rpy), np.array(b.half_extents)))
    return np.concatenate(pts)


def place(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    return points @ pose[:3, :3].T + pose[:3, 3]


def angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.acos(max(-1.0, min(1.0, float(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b)))))


def orientation_problem(hand: Gripper, rot: np.ndarray) -> str | None:
    if hand.approach is not None and angle(rot[:, 2], np.array(hand.approach)) > (
        hand.approach_tolerance + 1e-6
    ):
        return "approach outside its cone"
    if hand.closing is not None:
        dev = angle(rot[:, 1], np.array(hand.closing))
        if min(dev, math.pi - dev) > hand.closing_tolerance + 1e-6:
            return "closing axis outside its cone"
    return None


def force_problem(
    inst: Any, action: str, mode: str, grasp: np.ndarray, hand: Gripper
) -> str | None:
    spec = inst.concept.actions[action]
    try:
        if spec.fixed_twist:
            raise eac.ParameterError("a twist")
        f = inst.force(action, grasp=grasp)
    except eac.ParameterError:
        if mode == "pinch" and spec.turns and hand.can_turn:
            return None
        return "a twist that this contact or hand cannot make"
    z, x = grasp[:3, 2], grasp[:3, 0]
    if mode in ("push", "press") and float(f @ z) < math.cos(CONE) - 1e-9:
        return "a push cannot pull"
    if mode == "hook" and (float(f @ x) <= 0 or float(f @ z) > math.cos(CONE)):
        return "a hook pulls only towards its wall"
    return None


def path_end(inst: Any, action: str) -> float | None:
    spec = inst.concept.actions[action]
    if spec.joint is None:
        return None
    lo, hi = inst.joint_limits()[spec.joint]
    q0 = inst.joints[spec.joint]
    end = hi if spec.opening else lo
    if not math.isfinite(end):
        end = q0 + (1 if spec.opening else -1) * math.pi / 2
    return None if abs(end - q0) < 1e-9 else end


def check(inst: Any, action: str, o: Any, hand: Gripper) -> tuple[str | None, float]:
    """The independent verdict on one option's pose: (problem or None, deepest penetration m)."""
    if o.hand_pose is None:
        return "no pose", 0.0
    width = inst.grasp_width(o.grasp) if o.mode == "pinch" else 0.0
    if o.mode == "pinch" and (not hand.can_close or (width or 0.0) > hand.max_width + 1e-9):
        return "the hand cannot make this pinch", 0.0
    why = force_problem(inst, action, o.mode, o.pose, hand)
    if why:
        return why, 0.0
    why = orientation_problem(hand, o.hand_pose[:3, :3])
    if why:
        return why, 0.0
    hold = min(hand.max_width, width if width is not None else hand.max_width)
    opened = min(hand.max_width, hold + 2 * CLEARANCE) if o.mode == "pinch" else hold
    n = o.pose[:3, 2]  # the contact's +z: the hand comes in along it
    steps = np.arange(hand.approach_distance, -1e-12, -APPROACH_STEP)
    open_pts = hand_points(hand, opened)
    clouds = [place(open_pts, o.hand_pose) - s * n for s in steps]
    if opened > hold:
        for w in np.arange(opened, hold - 1e-12, -0.001):
            clouds.append(place(hand_points(hand, float(w), fingers_only=True), o.hand_pose))
    deepest = -float(inst.sdf(np.concatenate(clouds)).min())
    if deepest > DEPTH + TIE:
        return "hand in the part on the approach", deepest
    end = path_end(inst, action)
    if end is None:
        return None, max(deepest, 0.0)
    spec = inst.concept.actions[action]
    path = inst.follow(action, grasp=o.hand_pose, to=end, steps=PATH_STEPS)
    if o.mode == "pinch":
        for pose in path:
            why = orientation_problem(hand, pose[:3, :3])
            if why:
                return why + " along the path", 0.0
            if not hand.can_turn and angle_of(path[0][:3, :3].T @ pose[:3, :3]) > TURN:
                return "the path turns a hand that cannot turn", 0.0
    held = hand_points(hand, hold)
    q0 = inst.joints[spec.joint]
    for pose, q in zip(path, np.linspace(q0, end, PATH_STEPS)):
        d = -float(inst.with_joints({spec.joint: float(q)}).sdf(place(held, pose)).min())
        deepest = max(deepest, d)
        if d > DEPTH + TIE:
            return "hand in the part along the path", deepest
    return None, max(deepest, 0.0)


def angle_of(r: np.ndarray) -> float:
    return math.acos(max(-1.0, min(1.0, (float(np.trace(r)) - 1) / 2)))


# ---- the run ------------------------------------------------------------------------------------


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--concepts", nargs="+", help="only these (default: every concept)")
    ap.add_argument("--hands", nargs="+", help="only these shipped hands (default: all)")
    ap.add_argument("--out", type=Path, default=RESULTS, help="where the JSON goes")
    ap.add_argument("--smoke", action="store_true", help="3 concepts, one pose: checks it runs")
    ap.add_argument(
        "--time", action="store_true", help="only time rank (the Panda, front facing the robot)"
    )
    ap.add_argument(
        "--merge",
        nargs="+",
        type=Path,
        metavar="JSON",
        help="combine the results of runs over parts of the library (e.g. --concepts in shards)",
    )
    args = ap.parse_args()
    if args.time:
        return time_rank(args)
    if args.merge:
        return merge(args.merge, args.out)
    poses = dict(POSES)
    if args.smoke:
        args.concepts = args.concepts or list(SMOKE)
        poses = {"facing": facing}
    started = time.perf_counter()
    lib = eac.load_library()
    hands = [Gripper.load(h) for h in (args.hands or Gripper.shipped())]
    rows: list[dict[str, Any]] = []
    rank_seconds: list[float] = []
    for name in args.concepts or verifiable(lib):
        for pose_name, pose in poses.items():
            inst = lib[name].instantiate(pose=pose())
            for action in inst.action_names:
                for hand in hands:
                    t0 = time.process_time()
                    options = inst.rank(action, hand)
                    rank_seconds.append(time.process_time() - t0)
                    for o in options:
                        problem, depth = check(inst, action, o, hand)
                        rows.append(
                            {
                                "concept": name,
                                "pose": pose_name,
                                "action": action,
                                "hand": hand.name,
                                "grasp": o.grasp,
                                "mode": o.mode,
                                "contact": o.contact,
                                "feasible": o.feasible,
                                "reasons": list(o.reasons),
                                "check": problem,
                                "depth_mm": round(depth * 1e3, 2),
                            }
                        )
    table = summarize(rows, [h.name for h in hands])
    for line in format_table(table):
        print(line)
    bad = [r for r in rows if r["feasible"] and r["check"]]
    silent = [r for r in rows if not r["feasible"] and not r["reasons"]]
    for r in bad[:20]:
        print(
            f"DISAGREE {r['concept']} {r['pose']} {r['action']} {r['hand']} {r['grasp']} "
            f"({r['contact']}): {r['check']} ({r['depth_mm']} mm)"
        )
    summary = {
        "command": " ".join(["bench/bench_rank_agreement.py", *sys.argv[1:]]),
        "concepts": len({r["concept"] for r in rows}),
        "poses": list(poses),
        "hands": table,
        "feasible_failing_check": bad,
        "rejected_without_reason": silent,
        "rank_ms_mean_cpu": round(1e3 * float(np.mean(rank_seconds)), 2) if rank_seconds else 0,
        "rank_calls": len(rank_seconds),
        "seconds_total": round(time.perf_counter() - started, 1),
        "settings": {
            "spacing_mm": SPACING * 1e3,
            "approach_step_mm": APPROACH_STEP * 1e3,
            "path_steps": PATH_STEPS,
            "depth_mm": DEPTH * 1e3,
        },
        "machine": {"python": platform.python_version(), "platform": platform.platform()},
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(summary, indent=1) + "\n")
    print(f"wrote {args.out} in {summary['seconds_total']} s")
    return 1 if bad or silent else 0


def merge(parts: list[Path], out: Path) -> int:
    """One table and JSON from runs over disjoint sets of concepts (same hands and poses)."""
    runs = [json.loads(p.read_text()) for p in parts]
    rows = [r for run in runs for r in run["rows"]]
    hands = list(runs[0]["hands"])
    table = summarize(rows, hands)
    for line in format_table(table):
        print(line)
    bad = [r for r in rows if r["feasible"] and r["check"]]
    silent = [r for r in rows if not r["feasible"] and not r["reasons"]]
    calls = sum(run["rank_calls"] for run in runs)
    merged = {
        "command": " ".join(["bench/bench_rank_agreement.py", *sys.argv[1:]]),
        "parts": [run["command"] for run in runs],
        "concepts": len({r["concept"] for r in rows}),
        "poses": runs[0]["poses"],
        "hands": table,
        "feasible_failing_check": bad,
        "rejected_without_reason": silent,
        "rank_ms_mean_cpu": round(
            sum(run["rank_ms_mean_cpu"] * run["rank_calls"] for run in runs) / max(calls, 1), 2
        ),
        "rank_calls": calls,
        "seconds_total": round(sum(run["seconds_total"] for run in runs), 1),
        "settings": runs[0]["settings"],
        "machine": runs[0]["machine"],
        "rows": rows,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(merged, indent=1) + "\n")
    print(f"{merged['concepts']} concepts, {calls} rank calls; wrote {out}")
    return 1 if bad or silent else 0


def time_rank(args: argparse.Namespace) -> int:
    """CPU time per ``inst.rank`` call over every action of the library (the Panda, or each of
    ``--hands``; default parameters, front facing the robot, 32 samples, best of 3 passes).
    Uses only what the runtime had before hands were described (with ``--hands``: before
    the contact search), so it times older checkouts too."""
    lib = eac.load_library()
    names = args.concepts or (list(SMOKE) if args.smoke else verifiable(lib))
    insts = [lib[n].instantiate(pose=facing()) for n in names]
    hands = [Gripper.load(h) for h in args.hands] if args.hands else [Gripper.panda()]
    calls = [(inst, a, h) for inst in insts for a in inst.action_names for h in hands]
    for inst, a, hand in calls:  # warm: native kernels loaded, sweeps cached
        inst.rank(a, hand)
    passes = []
    for _ in range(3):
        t0 = time.process_time()
        for inst, a, hand in calls:
            inst.rank(a, hand)
        passes.append((time.process_time() - t0) / len(calls))
    ms = round(1e3 * min(passes), 2)
    print(f"{len(calls)} rank calls: {ms} ms CPU per call (best of 3)")
    out = {
        "command": " ".join(["bench/bench_rank_agreement.py", *sys.argv[1:]]),
        "hands": [h.name for h in hands],
        "rank_calls": len(calls),
        "ms_cpu_per_rank": ms,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    return 0


def summarize(rows: list[dict[str, Any]], hands: list[str]) -> dict[str, dict[str, int]]:
    out = {}
    for h in hands:
        mine = [r for r in rows if r["hand"] == h]
        feasible = [r for r in mine if r["feasible"]]
        rejected = [r for r in mine if not r["feasible"]]
        out[h] = {
            "options": len(mine),
            "feasible": len(feasible),
            "feasible_pass_check": sum(not r["check"] for r in feasible),
            "rejected": len(rejected),
            "rejected_with_reason": sum(bool(r["reasons"]) for r in rejected),
            "rejected_failing_check": sum(bool(r["check"]) for r in rejected),
        }
    return out


def format_table(table: dict[str, dict[str, int]]) -> list[str]:
    head = (
        f"{'hand':8s} {'options':>7s} {'feasible':>8s} {'agree':>6s} {'rejected':>8s} "
        f"{'reason':>6s} {'also fail':>9s}"
    )
    lines = [head]
    for h, t in table.items():
        lines.append(
            f"{h:8s} {t['options']:7d} {t['feasible']:8d} {t['feasible_pass_check']:6d} "
            f"{t['rejected']:8d} {t['rejected_with_reason']:6d} {t['rejected_failing_check']:9d}"
        )
    return lines


if __name__ == "__main__":
    sys.exit(main())
