"""Which repeated and variant members an instance has.

A concept with ``for i in 0..n`` is compiled once, unrolled to the largest count (masking, see
``docs/benchmarks.md``); the manifest's ``masks`` say when each copy exists (``drawer[2]``: when
``n > 2``) and its ``variants`` which part each option of a ``match`` places (``handle`` is
``handle@bar`` when ``kind == "bar"``).  Here the runtime reads them: an instance with ``n = 2``
has no ``drawer[2]`` (a typed error naming the valid indices), and ``handle.pull`` means the
grasp of the option the instance has chosen.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import Any

from grace_dsl.runtime.errors import UnknownNameError

_INDEXED = re.compile(r"^(.*?)((?:\[-?\d+\])+)$")


def has_masks(entry: Mapping[str, Any]) -> bool:
    """Whether a concept has repeated or variant members at all (the fast path skips the rest)."""
    return bool(entry.get("masks") or entry.get("variants"))


def canonical(entry: Mapping[str, Any], params: Mapping[str, Any], name: str, kind: str) -> str:
    """The compiled name that ``name`` (a ``kind``: grasp, action, link, ...) means for an
    instance with these parameter values: variant parts read through their chosen option;
    ``UnknownNameError`` for a copy the instance does not have."""
    masks = entry.get("masks") or {}
    variants = entry.get("variants") or {}
    out = ""
    for segment in name.split("."):
        here = out + segment
        if here in variants:
            v = variants[here]
            here = v["options"].get(str(params.get(v["param"])), here)
        why = _absent(masks, params, here)
        if why is not None:
            raise UnknownNameError(
                f"{entry['name']} has no {kind} {name!r} at {why}"
                + _valid(entry, params, here, masks, variants)
            )
        out = here + "."
    return out[:-1]


def present(entry: Mapping[str, Any], params: Mapping[str, Any], name: str) -> bool:
    """Whether the compiled member ``name`` exists at these parameter values."""
    masks = entry.get("masks") or {}
    parts = name.split(".")
    return all(_absent(masks, params, ".".join(parts[: i + 1])) is None for i in range(len(parts)))


def presence(entry: Mapping[str, Any], params: Mapping[str, Any]) -> Callable[[str], bool]:
    """A test of which members (``drawer[2].pull``, ``handle@bar.pull``) an instance with these
    parameters has: every name for a concept without repeats or variants."""
    if not has_masks(entry):
        return lambda name: True
    return lambda name: present(entry, params, name)


def count(entry: Mapping[str, Any], params: Mapping[str, Any], base: str) -> int:
    """How many copies of the repeated member ``base`` (``drawer``) an instance has."""
    return len(indices(entry, params, base))


def indices(entry: Mapping[str, Any], params: Mapping[str, Any], base: str) -> list[str]:
    """The indices (``[0]``, ``[1][2]``) of the copies of ``base`` an instance has."""
    masks = entry.get("masks") or {}
    found: list[str] = []
    for name in _members(entry):
        m = _INDEXED.match(name)
        present_copy = m is not None and m.group(1) == base and _absent(masks, params, name) is None
        if present_copy and m is not None and m.group(2) not in found:
            found.append(m.group(2))
    if not found and not any(
        (m := _INDEXED.match(n)) is not None and m.group(1) == base for n in _members(entry)
    ):
        raise UnknownNameError(f"{entry['name']} repeats nothing called {base!r}")
    return found


def _members(entry: Mapping[str, Any]) -> list[str]:
    names: list[str] = []
    for kind in ("links", "joints", "grasps", "actions", "shapes"):
        names += [e["name"] for e in entry.get(kind, ())]
    names += list(entry.get("parts", {}))
    names += list(entry.get("variants", {}))
    out: list[str] = []
    for n in names:  # every dotted prefix: `drawer[2]` of `drawer[2].handle.pull`
        parts = n.split(".")
        out += [".".join(parts[: i + 1]) for i in range(len(parts))]
    return list(dict.fromkeys(out))


def _absent(masks: Mapping[str, Any], params: Mapping[str, Any], name: str) -> str | None:
    for param, value in masks.get(name, ()):
        if not param:  # its host binds a count or a choice that leaves it out
            return "the values its host binds"
        have = params.get(param)
        if isinstance(value, str):
            if have != value:
                return f'{param} = "{have}"'
        elif have is None or not float(have) > value:
            return f"{param} = {int(have) if have is not None else '?'}"
    return None


def _valid(
    entry: Mapping[str, Any],
    params: Mapping[str, Any],
    name: str,
    masks: Mapping[str, Any],
    variants: Mapping[str, Any],
) -> str:
    m = _INDEXED.match(name.split("@")[0])
    if m is None:
        return ""
    base = m.group(1)
    try:
        have = indices(entry, params, base)
    except UnknownNameError:
        return ""
    if not have:
        return f"; it has no {base} at all"
    return f"; its {base} has indices " + ", ".join(have)


def repeats(entry: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Every repeated member by its base name (``drawer``): its indices, and the count
    parameters that decide which copies exist (what a prompt shows instead of the copies)."""
    masks = entry.get("masks") or {}
    out: dict[str, dict[str, Any]] = {}
    for name in _members(entry):
        m = _INDEXED.match(name)
        if m is None or "@" in name.rsplit(".", 1)[-1]:
            continue
        rep = out.setdefault(m.group(1), {"indices": [], "counts": []})
        if m.group(2) not in rep["indices"]:
            rep["indices"].append(m.group(2))
        for param, value in masks.get(name, ()):
            if not isinstance(value, str) and param not in rep["counts"]:
                rep["counts"].append(param)
    return out
