"""Hand description files: a small TOML format a user writes for their own hand.

Why a format and not Python: a hand is data (sizes, cones, flags), and users share it as a file;
parsing it is validation only, never evaluation. Every length and angle carries its unit in the
text (``"80 mm"``, ``"17.5 15.2 18.5 mm"``, ``"20 deg"``), so a file cannot silently mix metres
and millimetres. An unknown key, a wrong unit, a negative size or a wrong type raises
:class:`HandFileError` naming the file, the line and the key. The format is documented in
``docs/api.md`` (hand description files); the shipped hands live in ``grace_dsl/hands/``.
"""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

from grace_dsl.runtime.concept import suggest
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import DEFAULT_PUSHES, PUSHES, Gripper, HandBox

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - the project's floor is 3.10
    import tomli as tomllib

FORMAT = 1
HANDS_DIR = Path(__file__).resolve().parent.parent / "hands"
LENGTH_UNITS = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
ANGLE_UNITS = {"deg": math.pi / 180.0, "rad": 1.0}
NUMBER = re.compile(r"[-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?\Z")

TOP_KEYS = {
    "format": "the format version, 1",
    "name": "the hand's name",
    "doc": "one line about the hand",
    "source": "where its numbers come from",
    "max_width": "widest opening between the pads (length)",
    "can_close": "whether the fingers close (bool)",
    "can_turn": "whether the hand may turn while it acts (bool)",
    "pushes": "what it pushes with: tip, side, palm",
    "approach_distance": "how far back the approach starts (length)",
    "pad": "table: the pads",
    "orientation": "table: the orientations the hand reaches",
    "finger": "array of tables: finger blocks",
    "palm": "array of tables: palm boxes",
}
PAD_KEYS = {"size"}
ORIENTATION_KEYS = {"approach", "approach_tolerance", "closing", "closing_tolerance"}
BOX_KEYS = {"name", "size", "at", "rpy"}


class HandFileError(ParameterError):
    """A hand description that cannot be read: where (file, line, key) and why."""

    def __init__(self, path: str, line: int | None, key: str, message: str):
        self.path, self.line, self.key = path, line, key
        at = f"{path}:{line}" if line else path
        super().__init__(f"{at}: {key}: {message}" if key else f"{at}: {message}")


def shipped_hands() -> tuple[str, ...]:
    """Names of the description files shipped in ``grace_dsl/hands``."""
    return tuple(sorted(p.stem for p in HANDS_DIR.glob("*.toml")))


def load_hand(path_or_name: str | Path) -> Gripper:
    """A ``Gripper`` from a description file, or a shipped hand by name."""
    if not isinstance(path_or_name, (str, Path)):
        raise ParameterError(
            f"a hand is a shipped name ({', '.join(shipped_hands())}) or a path to a .toml "
            f"file, not {path_or_name!r:.60}"
        )
    text = str(path_or_name)
    if isinstance(path_or_name, str) and re.fullmatch(r"[A-Za-z0-9_-]+", text):
        shipped = HANDS_DIR / f"{text}.toml"
        if shipped.is_file():
            return _load_file(str(shipped))
        if not Path(text).exists():
            raise ParameterError(
                f"no shipped hand {text!r}"
                + suggest(text, shipped_hands() or ["(none)"])
                + f"; shipped: {', '.join(shipped_hands())}, or give a path to a .toml file"
            )
    return _load_file(str(Path(text).resolve()))


@lru_cache(maxsize=64)
def _load_file_cached(path: str, mtime_ns: int) -> Gripper:
    source = Path(path).read_text(encoding="utf-8")
    return parse_hand(source, path)


def _load_file(path: str) -> Gripper:
    try:
        mtime = Path(path).stat().st_mtime_ns
    except OSError as exc:
        raise ParameterError(f"cannot read hand file {path}: {exc.strerror}") from None
    try:
        return _load_file_cached(path, mtime)
    except UnicodeDecodeError:
        raise ParameterError(f"{path}: a hand file is UTF-8 text") from None
    except OSError as exc:
        raise ParameterError(f"cannot read hand file {path}: {exc.strerror}") from None


def parse_hand(text: str, path: str = "<hand>") -> Gripper:
    """Parse and validate a description (see the module docstring); never evaluates text."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        line = re.search(r"line (\d+)", str(exc))
        at = int(line.group(1)) if line else None
        raise HandFileError(path, at, "", f"not TOML: {exc}") from None
    return _Reader(text, path).hand(data)


class _Reader:
    """Reads one parsed file, locating each complaint on its line."""

    def __init__(self, text: str, path: str):
        self.lines, self.path = text.splitlines(), path

    def fail(self, key: str, message: str) -> HandFileError:
        return HandFileError(self.path, self._line(key), key, message)

    def _line(self, key: str) -> int | None:
        """The line of ``key`` (``table.key``, ``finger[1].size``): best effort, by text."""
        parts = re.match(r"(?:(\w+)(?:\[(\d+)\])?\.)?(\w+)\Z", key)
        if parts is None:
            return None
        table, index, name = parts.group(1), parts.group(2), parts.group(3)
        start = 0
        if table is not None:
            header = re.compile(rf"\s*\[\[?\s*{table}\s*\]\]?")
            hits = [i for i, line in enumerate(self.lines) if header.match(line)]
            pick = int(index) if index is not None else 0
            if pick >= len(hits):
                return None
            start = hits[pick]
        assign = re.compile(rf"\s*{name}\s*=")
        for i in range(start, len(self.lines)):
            if i > start and table is not None and self.lines[i].lstrip().startswith("["):
                break
            if table is None and self.lines[i].lstrip().startswith("["):
                break
            if assign.match(self.lines[i]):
                return i + 1
        return start + 1 if table is not None else None

    # -- the whole file
    def hand(self, data: Mapping[str, Any]) -> Gripper:
        self.known(data, set(TOP_KEYS), "")
        fmt = data.get("format", FORMAT)
        if fmt != FORMAT or isinstance(fmt, bool):
            raise self.fail("format", f"this reader knows format {FORMAT}, got {fmt!r}")
        if "name" not in data:
            raise self.fail("name", "missing: every hand has a name")
        name = self.text(data, "name")
        if not name.strip():
            raise self.fail("name", "must not be empty")
        if "max_width" not in data:
            raise self.fail(
                "max_width",
                'missing: the widest opening, e.g. "80 mm" (0: a hand whose fingers do not open)',
            )
        max_width = self.length(data["max_width"], "max_width", zero=True)
        pad = self.table(data, "pad")
        self.known(pad, PAD_KEYS, "pad")
        if "size" not in pad:
            raise self.fail("pad.size", 'missing: the pad\'s size x y z, e.g. "17.5 15.2 18.5 mm"')
        size = self.lengths(pad["size"], "pad.size", 3)
        orient = self.table(data, "orientation")
        self.known(orient, ORIENTATION_KEYS, "orientation")
        pushes = data.get("pushes", list(DEFAULT_PUSHES))
        if not isinstance(pushes, list) or not all(p in PUSHES for p in pushes):
            raise self.fail("pushes", f"a list of {', '.join(PUSHES)}, got {pushes!r}")
        can_close = self.flag(data, "can_close", True)
        if can_close and max_width == 0:
            raise self.fail("max_width", "is 0 but can_close is true: a hand that closes opens")
        return Gripper(
            name=name,
            max_width=max_width,
            finger_width=size[0],
            finger_thickness=size[1],
            finger_length=size[2],
            can_close=can_close,
            approach=self.direction(orient, "approach"),
            approach_tolerance=self.angle_or(orient, "approach_tolerance"),
            closing=self.direction(orient, "closing"),
            closing_tolerance=self.angle_or(orient, "closing_tolerance"),
            can_turn=self.flag(data, "can_turn", True),
            fingers=self.boxes(data, "finger"),
            palm=self.boxes(data, "palm"),
            pushes=tuple(dict.fromkeys(pushes)),
            approach_distance=self.length(
                data.get("approach_distance", "80 mm"), "approach_distance", zero=True
            ),
            doc=self.text(data, "doc") if "doc" in data else "",
        )

    def known(self, table: Mapping[str, Any], keys: set[str], where: str) -> None:
        for key in table:
            if key not in keys:
                full = f"{where}.{key}" if where else key
                raise self.fail(full, "unknown key" + suggest(key, sorted(keys)))

    def table(self, data: Mapping[str, Any], key: str) -> Mapping[str, Any]:
        value = data.get(key, {})
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a table ([{key}]), got {type(value).__name__}")
        return value

    def text(self, data: Mapping[str, Any], key: str) -> str:
        value = data[key]
        if not isinstance(value, str):
            raise self.fail(key, f"must be text in quotes, got {value!r}")
        return value

    def flag(self, data: Mapping[str, Any], key: str, default: bool) -> bool:
        value = data.get(key, default)
        if not isinstance(value, bool):
            raise self.fail(key, f"must be true or false, got {value!r}")
        return value

    # -- quantities
    def quantity(
        self, value: Any, key: str, count: int, units: Mapping[str, float], what: str
    ) -> list[float]:
        """``count`` numbers followed by one unit of ``units``, e.g. "17.5 15.2 18.5 mm"."""
        example = " ".join(["10"] * count) + f" {next(iter(units))}"
        if not isinstance(value, str):
            raise self.fail(key, f'a {what} is text with its unit, e.g. "{example}"; got {value!r}')
        words = value.split()
        if not words or NUMBER.match(words[-1]):
            raise self.fail(
                key, f'{value!r} has no unit; write e.g. "{example}" (units: {", ".join(units)})'
            )
        unit, numbers = words[-1], words[:-1]
        if unit not in units:
            other = (
                "an angle"
                if unit in ANGLE_UNITS
                else "a length"
                if unit in LENGTH_UNITS
                else "not a unit"
            )
            raise self.fail(
                key, f"wrong unit {unit!r} ({other}): {key} is {what}, in {', '.join(units)}"
            )
        if len(numbers) != count or not all(NUMBER.match(n) for n in numbers):
            raise self.fail(
                key,
                f"expected {count} number{'s' * (count > 1)} then the unit, "
                f'e.g. "{example}"; got {value!r}',
            )
        out = [float(n) * units[unit] for n in numbers]
        if not all(math.isfinite(x) for x in out):
            raise self.fail(key, f"not finite: {value!r}")
        return out

    def length(self, value: Any, key: str, zero: bool = False) -> float:
        (x,) = self.quantity(value, key, 1, LENGTH_UNITS, "a length")
        if x < 0 or (x == 0 and not zero):
            raise self.fail(
                key, f"must be a {'non-negative' if zero else 'positive'} length, got {value!r}"
            )
        return x

    def lengths(self, value: Any, key: str, count: int, positive: bool = True) -> list[float]:
        out = self.quantity(value, key, count, LENGTH_UNITS, "a length")
        if positive and not all(x > 0 for x in out):
            raise self.fail(key, f"every size must be positive, got {value!r}")
        return out

    def angle_or(self, table: Mapping[str, Any], key: str) -> float:
        if key not in table:
            return math.pi
        (a,) = self.quantity(table[key], f"orientation.{key}", 1, ANGLE_UNITS, "an angle")
        if not 0 <= a <= math.pi:
            raise self.fail(f"orientation.{key}", f"must lie in [0, 180] deg, got {table[key]!r}")
        return a

    def direction(self, table: Mapping[str, Any], key: str) -> tuple[float, float, float] | None:
        if key not in table:
            return None
        value = table[key]
        ok = (
            isinstance(value, list)
            and len(value) == 3
            and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in value
            )
        )
        if not ok or not any(value):
            raise self.fail(
                f"orientation.{key}",
                f"a world direction is three numbers, not all 0, e.g. [0, 0, -1]; got {value!r}",
            )
        return (float(value[0]), float(value[1]), float(value[2]))

    def boxes(self, data: Mapping[str, Any], key: str) -> tuple[HandBox, ...]:
        entries = data.get(key, [])
        if isinstance(entries, dict) or not isinstance(entries, list):
            raise self.fail(key, f"write each box as its own [[{key}]] table")
        out = []
        for i, entry in enumerate(entries):
            where = f"{key}[{i}]"
            self.known(entry, BOX_KEYS, where)
            for need in ("size", "at"):
                if need not in entry:
                    raise self.fail(f"{where}.{need}", "missing")
            size = self.lengths(entry["size"], f"{where}.size", 3)
            at = self.lengths(entry["at"], f"{where}.at", 3, positive=False)
            rpy = [0.0, 0.0, 0.0]
            if "rpy" in entry:
                rpy = self.quantity(entry["rpy"], f"{where}.rpy", 3, ANGLE_UNITS, "an angle")
            name = entry.get("name", f"{key}{i}")
            if not isinstance(name, str):
                raise self.fail(f"{where}.name", f"must be text in quotes, got {name!r}")
            out.append(HandBox(name, _triple(at), _triple([s / 2 for s in size]), _triple(rpy)))
        return tuple(out)


def _triple(v: list[float]) -> tuple[float, float, float]:
    return (v[0], v[1], v[2])
