"""The prompt catalog: every concept of a library as a vision-language model reads it.

GRACE grounds an instruction in two steps: the model first reads every concept's synopsis and
picks the part concept, then reads that concept's manipulation blueprint (grasp families, actions,
force rules) and picks the manipulation function. The catalog gives it both, from the compiled
manifest (parameters, joints, grasps, actions, SymPy formulas) and the ``.eac`` sources (the pose,
range and axis expressions as written, which read better than any expanded formula).

``build_catalog`` makes plain data (the JSON schema in docs/api.md); ``render_markdown`` and
``render_json`` print it. Values are SI in the data and shown in mm and degrees in the text.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.compiler.expand import expand
from grace_dsl.compiler.manifest import source_text
from grace_dsl.compiler.types import format_si
from grace_dsl.lang import ast
from grace_dsl.lang.parser import parse
from grace_dsl.runtime import masks
from grace_dsl.runtime.concept import suggest
from grace_dsl.runtime.errors import UnknownNameError
from grace_dsl.runtime.library import Concept, Library

SCHEMA = "grace-eac.prompt-catalog/1"
SHORT = 110  # characters: longer SymPy texts stay out of the markdown (they are in the JSON)

CONVENTIONS = {
    "units": "SI inside (metres, radians); the text shows lengths in mm and angles in deg, "
    "as the .eac sources write them",
    "concept_frame": "origin at the centre of the main body, +z out of the front face (the side "
    "a robot approaches), +y up",
    "gripper_frame": "a grasp pose G is the gripper frame: origin between the fingertips, +z the "
    "approach direction (into the part), +y the direction in which the fingers close",
    "poses": "G is given in the concept frame; in the world G_world = M G, with M the pose of "
    "the concept; trans(x, y, z) translates, rotx/roty/rotz(a) rotate about an axis, "
    "rpy(r, p, y) = rotz(y) roty(p) rotx(r); * composes left to right",
    "joints": "q_<joint> is a joint's value: 0 closed, positive opens, within its range",
    "parts": "a part's own expressions (its grasp poses, ranges and axes) use the part's "
    "parameter names: `length` of part `handle` is the concept's parameter `handle.length`",
    "forces": "F is the unit direction in which the gripper must move the grasp point "
    "(x_g, y_g, z_g), in the concept frame; F_world = R F with R the rotation of M",
}


# ---- the data --------------------------------------------------------------------------------


def build_catalog(lib: Library, names: Sequence[str] | None = None) -> dict[str, Any]:
    """The catalog of ``names`` (default: every concept of ``lib``), grouped by source file.

    Raises ``UnknownNameError`` for a name that is not in the library."""
    for name in names or ():
        if name not in lib:
            raise UnknownNameError(f"no concept {name!r} in the library" + suggest(name, lib))
    wanted = list(dict.fromkeys(names)) if names else list(lib)
    sources = _Sources(lib)
    categories: dict[str, list[dict[str, Any]]] = {}
    for name in wanted:
        concept = lib[name]
        categories.setdefault(concept.entry["file"], []).append(_concept(lib, concept, sources))
    return {
        "schema": SCHEMA,
        "conventions": dict(CONVENTIONS),
        "categories": [
            {"name": Path(file).stem, "file": file, "concepts": concepts}
            for file, concepts in sorted(categories.items(), key=lambda kv: _order(kv[0]))
        ],
    }


def _order(file: str) -> tuple[int, str]:
    """Building blocks last: a model picks among articulated objects and their parts first."""
    return (1 if file == "primitives.eac" else 0, file)


class _Sources:
    """The syntax trees of a library's source files, parsed on demand (none for an artifact)."""

    def __init__(self, lib: Library):
        self._texts = dict(lib.result.sources) if lib.result is not None else {}
        self._concepts: dict[str, tuple[ast.Concept, str]] | None = None

    def concept(self, name: str) -> tuple[ast.Concept, str] | None:
        if self._concepts is None:
            self._concepts = {}
            for path, text in sorted(self._texts.items()):
                module = parse(text, path).module
                if module is not None:  # loops unrolled: `drawer[2]` is found like `drawer`
                    module = expand(module)[0]
                for decl in module.concepts if module else ():
                    self._concepts.setdefault(decl.name, (decl, text))
        return self._concepts.get(name)


def _members(decl: ast.Concept) -> Iterator[tuple[Any, str]]:  # (member, link)
    """Every member with the link that holds it (``base`` outside any link)."""
    for m in decl.members:
        if isinstance(m, ast.Link):
            yield from ((inner, m.name) for inner in m.members)
        yield m, "base"


def _member(sources: _Sources, concept: str, kind: type, name: str) -> tuple[Any, str, str] | None:
    """The declaration ``name`` of type ``kind`` in ``concept``: (node, link, source text)."""
    found = sources.concept(concept)
    if found is None:
        return None
    decl, text = found
    for m, link in _members(decl):
        if isinstance(m, kind) and getattr(m, "name", None) == name:
            return m, link, text
    return None


def _src(text: str, node: Any) -> str | None:
    """The source of a node as written (None for an absent node)."""
    if node is None:
        return None
    return source_text(text, node.span) or None


def _concept(lib: Library, c: Concept, sources: _Sources) -> dict[str, Any]:
    inst = c.instantiate() if c.grasps or c.joints else None
    params = inst.params if inst is not None and masks.has_masks(c.entry) else {}

    def here(name: str) -> Any:  # the instance at the defaults, if it has this member
        return inst if not params or masks.present(c.entry, params, name) else None

    return {
        "name": c.name,
        "kind": c.entry["kind"],
        "file": c.entry["file"],
        "doc": c.doc,
        "params": [_param(p) for p in c.params],
        "requires": [dict(r) for r in c.entry["requires"]],
        "parts": [_part(c, name, sources) for name in c.parts],
        "links": [dict(link) for link in c.entry["links"]],
        "joints": [_joint(c, j, here(j["name"]), sources) for j in c.joints.values()],
        "grasps": [_grasp(lib, c, g, here(g["name"]), sources) for g in c.grasps.values()],
        "actions": [_action(c, a) for a in c.actions.values()],
        "repeats": masks.repeats(c.entry),
        "variants": {
            name: {
                "param": v["param"],
                "options": {o: c.parts[part] for o, part in v["options"].items()},
                "parts": dict(v["options"]),
            }
            for name, v in (c.entry.get("variants") or {}).items()
        },
    }


def _si(value: Any) -> Any:
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, tuple):
        return [float(x) for x in value]
    return float(value)


def _param(p: Any) -> dict[str, Any]:
    default = p.decode(np.atleast_1d(p.default)) if p.kind in ("choice", "bool") else p.default
    return {
        "name": p.name,
        "type": p.type,
        "dim": p.dim,
        "size": p.size,
        "range": None if p.lo is None else [_si(p.lo), _si(p.hi)],
        "range_text": None if p.lo is None else f"[{_show(p.lo, p.dim)}, {_show(p.hi, p.dim)}]",
        "default": _si(default),
        "default_text": _show(default, p.dim),
        "choices": list(p.choices) if p.choices else None,
        "help": p.help,
        "doc": p.doc,
    }


def _show(value: Any, dim: str | None) -> str:
    """A value as the sources write it (``fmt_value`` of the command line)."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return format_si(value, dim)


def _split(qualified: str) -> tuple[str | None, str]:
    """``handle.pull`` -> ("handle", "pull"); ``pull`` -> (None, "pull")."""
    part, _, name = qualified.rpartition(".")
    return (part or None), name


def _declaring(c: Concept, part: str | None) -> str:
    """The concept that declares a member of part ``part`` (the host itself for None)."""
    return c.name if part is None else c.parts[part]


def _part(c: Concept, name: str, sources: _Sources) -> dict[str, Any]:
    parent, own = _split(name)
    found = _member(sources, _declaring(c, parent), ast.Part, own)
    link = at = None
    if found is not None:
        node, declared_on, text = found
        at = _src(text, node.at)
        if parent is None:  # a nested part's link is its own part's business
            link = declared_on
    return {"name": name, "concept": c.parts[name], "link": link, "at": at}


def _joint(c: Concept, j: Mapping[str, Any], inst: Any, sources: _Sources) -> dict[str, Any]:
    part, own = _split(j["name"])
    found = _member(sources, _declaring(c, part), ast.Joint, own)
    axis = origin = limits_src = None
    if found is not None:
        node, _, text = found
        axis, origin = _src(text, node.axis), _src(text, node.origin)
        bounds = _src(text, node.limits)
        limits_src = f"[{bounds}]" if bounds else None
    axis_value = limits = None
    if j["index"] is not None and inst is not None:
        axes, _ = c.function("joint_axes")(inst.p, inst.q)
        axis_value = [
            float(round(x, 12)) + 0.0 for x in np.asarray(axes).reshape(-1, 3)[j["index"]]
        ]
        lo, hi = inst.joint_limits()[j["name"]]
        limits = [lo, hi]
    unit = "length" if j["kind"] == "prismatic" else "angle"
    return {
        "name": j["name"],
        "kind": j["kind"],
        "parent": j["parent"],
        "child": j["child"],
        "doc": j["doc"],
        "frame": "concept" if part is None else f"part {part}",
        "axis": axis,
        "origin": origin,
        "range": limits_src,
        "axis_value": axis_value,
        "limits": limits,
        "limits_text": None
        if limits is None or not all(np.isfinite(limits))
        else f"[{_show(limits[0], unit)}, {_show(limits[1], unit)}]",
    }


def _grasp(
    lib: Library, c: Concept, g: Mapping[str, Any], inst: Any, sources: _Sources
) -> dict[str, Any]:
    part, own = _split(g["name"])
    home = _declaring(c, part)
    found = _member(sources, home, ast.Grasp, own)
    node, text = (found[0], found[2]) if found is not None else (None, "")
    ranges = inst.grasp_range(g["name"]) if inst is not None else {}
    free = []
    for k, f in enumerate(g["free"]):
        fnode = node.free[k] if node is not None and k < len(node.free) else None
        lo, hi = ranges.get(f["name"], (None, None))
        free.append(
            {
                "name": f["name"],
                "type": f["type"],
                "dim": f["dim"],
                "range": None
                if fnode is None
                else f"[{_src(text, fnode.lo)}, {_src(text, fnode.hi)}]",
                "default": None if fnode is None else _src(text, fnode.default),
                "at_defaults": None if lo is None else [lo, hi],
                "at_defaults_text": None
                if lo is None
                else f"[{_show(lo, f['dim'])}, {_show(hi, f['dim'])}]",
            }
        )
    width = None
    if g["has_width"]:
        value = inst.grasp_width(g["name"]) if inst is not None else None
        width = {
            "expression": _src(text, node.width) if node is not None else None,
            "value": value,
            "text": None if value is None else _show(value, "length"),
        }
    source = g["source"] or (lib[home].grasps[own]["source"] if home in lib else "")
    rows = _matrix_rows(g["formula"]["text"])
    names = {p.name: p for p in c.params}
    translation = rotation = None
    if part is None and rows is not None:
        translation = _readable(f"[{rows[0][3]}, {rows[1][3]}, {rows[2][3]}]", names)
        rotation = _readable(
            "[" + ", ".join(f"[{', '.join(r[:3])}]" for r in rows[:3]) + "]", names
        )
    placement = _part(c, part, sources) if part is not None else None
    return {
        "name": g["name"],
        "part": part,
        "part_concept": c.parts.get(part) if part is not None else None,
        "link": g["link"],
        "doc": g["doc"],
        "mode": g.get("mode", "pinch"),
        "symmetric": bool(g.get("symmetric")),
        "free": free,
        "width": width,
        "pose": {
            "source": source,
            "frame": "concept" if part is None else f"part {part}",
            "placement": None if placement is None else placement["at"],
            "translation": translation,
            "rotation": rotation,
            "text": _readable(g["formula"]["text"], names),
            "latex": g["formula"]["latex"],
        },
    }


def _action(c: Concept, a: Mapping[str, Any]) -> dict[str, Any]:
    names = {p.name: p for p in c.params}
    formula = a.get("formula") or {}
    return {
        "name": a["name"],
        "verb": a["verb"],
        "joint": a["joint"],
        "sense": a["sense"],
        "doc": a["doc"],
        "using": list(a["using"]),
        "force": {
            "text": _readable(formula.get("text", ""), names),
            "rest_text": _readable(formula.get("rest_text", ""), names),
            "latex": formula.get("latex", ""),
            "rest_latex": formula.get("rest_latex", ""),
            "normalize": bool(formula.get("normalize", False)),
        },
    }


# ---- SymPy text made readable (no evaluation: only bracket matching) ---------------------------


def _split_top(text: str) -> list[str]:
    """Split at the commas outside any bracket."""
    out, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append(text[start:i].strip())
            start = i + 1
    out.append(text[start:].strip())
    return out


def _matrix_rows(text: str) -> list[list[str]] | None:
    """The entries of a 4x4 ``[[...], ...]`` SymPy text, or None if it is not one."""
    text = text.strip()
    if not (text.startswith("[") and text.endswith("]")):
        return None
    rows = [r.strip() for r in _split_top(text[1:-1])]
    if len(rows) != 4 or not all(r.startswith("[") and r.endswith("]") for r in rows):
        return None
    cells = [_split_top(r[1:-1]) for r in rows]
    return cells if all(len(r) == 4 for r in cells) else None


def _closing(text: str, open_at: int) -> int:
    """The index of the bracket that closes the one at ``open_at``."""
    depth = 0
    for i in range(open_at, len(text)):
        if text[i] in "([{":
            depth += 1
        elif text[i] in ")]}":
            depth -= 1
            if depth == 0:
                return i
    return -1


_EQ = re.compile(r"Eq\(([A-Za-z_][\w.]*), (\d+)\)")


def _readable(text: str, params: Mapping[str, Any]) -> str:
    """SymPy text with choices spelled out: ``Eq(hinge_side, 0)`` -> ``hinge_side == "left"``,
    and ``Piecewise((a, c), (b, True))`` -> ``(a if c else b)``."""

    def choice(m: re.Match[str]) -> str:
        p = params.get(m.group(1))
        k = int(m.group(2))
        if p is not None and p.choices and k < len(p.choices):
            return f'{m.group(1)} == "{p.choices[k]}"'
        return f"{m.group(1)} == {k}"

    return _EQ.sub(choice, _piecewise(text))


def _piecewise(text: str) -> str:
    start = text.find("Piecewise(")
    if start < 0:
        return text
    open_at = start + len("Piecewise")
    end = _closing(text, open_at)
    if end < 0:
        return text
    branches = []
    for b in _split_top(text[open_at + 1 : end]):
        inner = _split_top(b[1:-1]) if b.startswith("(") and b.endswith(")") else []
        if len(inner) != 2:
            return text[:end] + _piecewise(text[end:])  # an unexpected form: leave it
        branches.append((_piecewise(inner[0]), _piecewise(inner[1])))
    expr = branches[-1][0] if branches[-1][1] == "True" else None
    if expr is None:
        return text[: end + 1] + _piecewise(text[end + 1 :])
    for value, cond in reversed(branches[:-1]):
        expr = f"{value} if {cond} else {expr}"
    return text[:start] + f"({expr})" + _piecewise(text[end + 1 :])


# ---- rendering -------------------------------------------------------------------------------


def render_json(catalog: Mapping[str, Any]) -> str:
    return json.dumps(catalog, indent=2, ensure_ascii=False) + "\n"


def render_markdown(catalog: Mapping[str, Any]) -> str:
    lines = [
        "# Concept catalog",
        "",
        "Every concept of the library with its parameters, structure, grasp families and "
        "actions, for a vision-language model that picks the part concept and the manipulation "
        "function. Generated by `eacc prompt`; do not edit.",
        "",
        "Conventions:",
        "",
        *(f"- **{k.replace('_', ' ')}**: {v}." for k, v in catalog["conventions"].items()),
        "",
        "## Synopses",
        "",
    ]
    for cat in catalog["categories"]:
        lines.append(f"- {_title(cat)}: " + ", ".join(f"`{c['name']}`" for c in cat["concepts"]))
        for c in cat["concepts"]:
            lines.append(f"  - `{c['name']}`: {_first_sentence(c['doc'])}")
    for cat in catalog["categories"]:
        lines += ["", f"## {_title(cat)}"]
        for c in cat["concepts"]:
            lines += ["", *_concept_md(c)]
    return "\n".join(lines).rstrip() + "\n"


def _title(cat: Mapping[str, Any]) -> str:
    return f"{cat['name'].replace('_', ' ').capitalize()} (`{cat['file']}`)"


def _first_sentence(doc: str) -> str:
    flat = " ".join(doc.split())
    m = re.search(r"(?<=[.!?])\s", flat)
    return (flat[: m.start()] if m else flat) or "(no synopsis)"


def _para(doc: str) -> str:
    return " ".join(doc.split())


def _concept_md(c: Mapping[str, Any]) -> list[str]:
    kind = " (primitive shape)" if c["kind"] == "primitive" else ""
    out = [f"### {c['name']}{kind}", ""]
    if c["doc"]:
        out += [_para(c["doc"]), ""]
    if c["params"]:
        out += [
            "Parameters:",
            "",
            "| name | type | range | default | meaning |",
            "| --- | --- | --- | --- | --- |",
        ]
        for p in c["params"]:
            meaning = " ".join(x for x in (p["help"] or "", _para(p["doc"])) if x)
            choices = " or ".join(f'"{x}"' for x in p["choices"] or ())
            out.append(
                f"| `{p['name']}` | {p['type']} | {p['range_text'] or choices or '-'} "
                f"| {p['default_text']} | {_cell(meaning)} |"
            )
        out.append("")
    if c["requires"]:
        messages = dict.fromkeys(r["message"] for r in c["requires"])
        out += ["Requires: " + "; ".join(messages) + ".", ""]
    if c.get("repeats"):
        out += ["Repeated members (copies past a count's value do not exist):", ""]
        for base, r in c["repeats"].items():
            counts = " and ".join(f"`{n}`" for n in r["counts"])
            out.append(
                f"- `{base}`: indices "
                + ", ".join(r["indices"])
                + (f", as many as {counts} says" if counts else "")
            )
        out.append("")
    if c.get("variants"):
        out += ["Variant parts (the choice parameter picks the part's concept):", ""]
        for name, v in c["variants"].items():
            options = ", ".join(f'"{o}" → {k} (`{v["parts"][o]}`)' for o, k in v["options"].items())
            out.append(
                f"- `{name}` by `{v['param']}`: {options}; `{name}.g` is the chosen "
                "option's grasp g"
            )
        out.append("")
    if c["parts"]:
        out += ["Parts:", ""]
        for p in c["parts"]:
            where = f" on link `{p['link']}`" if p["link"] else ""
            at = f", placed at `{p['at']}`" if p["at"] else ""
            out.append(f"- `{p['name']}`: {p['concept']}{where}{at}")
        out.append("")
    if len(c["links"]) > 1:
        out.append(
            "Links: "
            + "; ".join(
                f"`{link['name']}`" + (f" ({_para(link['doc'])})" if link["doc"] else "")
                for link in c["links"]
            )
        )
        out.append("")
    if c["joints"]:
        out += ["Joints:", ""]
        out += [_joint_md(j) for j in c["joints"]]
        out.append("")
    if c["grasps"]:
        out += ["Grasps:", ""]
        for g in c["grasps"]:
            out += _grasp_md(g)
        out.append("")
    if c["actions"]:
        out += ["Actions:", ""]
        for a in c["actions"]:
            out += _action_md(a)
        out.append("")
    return out[:-1] if out[-1] == "" else out


def _cell(text: str) -> str:
    return text.replace("|", "\\|") or "-"


def _vec(v: Sequence[float]) -> str:
    return "(" + ", ".join(f"{x:g}" for x in v) + ")"


_UNITS = frozenset(("mm", "cm", "m", "deg", "rad"))
_IDENT = re.compile(r"[A-Za-z_][\w.]*")


def _has_names(src: str) -> bool:
    """Whether a source expression depends on parameters (names other than unit suffixes)."""
    return any(w not in _UNITS for w in _IDENT.findall(re.sub(r"\d+(\.\d*)?[a-z]+", "", src)))


def _joint_md(j: Mapping[str, Any]) -> str:
    text = f"- `{j['name']}`: {j['kind']}, `{j['parent']}` → `{j['child']}`"
    if j["axis"]:
        frame = "" if j["frame"] == "concept" else f" (in the {j['frame']}'s frame)"
        text += f", axis `{j['axis']}`{frame}"
        if j["axis_value"] is not None and (_has_names(j["axis"]) or j["frame"] != "concept"):
            text += f" = {_vec(j['axis_value'])} at the defaults"
    if j["origin"]:
        text += f", through `{j['origin']}`"
    if j["range"]:
        text += f", range `{j['range']}`"
        if j["limits_text"] and _has_names(j["range"]):
            text += f" = {j['limits_text']} at the defaults"
    return text + (f". {_para(j['doc'])}" if j["doc"] else "")


def _grasp_md(g: Mapping[str, Any]) -> list[str]:
    how = g["mode"] + (", symmetric" if g["symmetric"] else "")
    where = (
        f"part `{g['part']}` ({g['part_concept']}), link `{g['link']}`"
        if g["part"]
        else f"link `{g['link']}`"
    )
    out = [f"- `{g['name']}` ({where}; by {how}): {_para(g['doc']) or '(no synopsis)'}"]
    for f in g["free"]:
        rng = f"`{f['range']}`" if f["range"] else ""
        at = f["at_defaults_text"]
        value = f"{rng} = {at} at the defaults" if rng and at else rng or at or "?"
        default = f", default `{f['default']}`" if f["default"] else ""
        out.append(f"  - free `{f['name']}` ({f['type']}) in {value}{default}")
    if g["width"]:
        w = g["width"]
        expr = f"`{w['expression']}`" if w["expression"] else ""
        value = f"{expr} = {w['text']} at the defaults" if expr and w["text"] else expr or w["text"]
        out.append(f"  - gripper opening: {value}")
    pose = g["pose"]
    if g["part"]:
        placed = f", with the part placed at `{pose['placement']}`" if pose["placement"] else ""
        out.append(f"  - pose in the part's frame: `G = {pose['source']}`{placed}")
    else:
        out.append(f"  - pose on link `{g['link']}`: `G = {pose['source']}`; in the concept frame:")
        for label in ("translation", "rotation"):
            if pose[label] and len(pose[label]) <= SHORT:
                out.append(f"    - {label}: `{pose[label]}`")
            elif pose[label]:
                out.append(f"    - {label}: (long; see the JSON catalog)")
    return out


def _action_md(a: Mapping[str, Any]) -> list[str]:
    if a["joint"]:
        what = f"{a['verb']} along `{a['joint']}` ({a['sense']})"
    else:
        what = f"{a['verb']} along a direction fixed to its link"
    using = ", using " + ", ".join(f"`{u}`" for u in a["using"]) if a["using"] else ""
    out = [f"- `{a['name']}`: {what}{using}. {_para(a['doc'])}".rstrip()]
    force = a["force"]
    if force["text"]:
        if force["text"] == force["rest_text"] or len(force["text"]) <= SHORT:
            out.append(f"  - force: `F = {force['text']}`")
        else:
            out.append(f"  - force with every joint at 0: `F = {force['rest_text']}`")
    return out
