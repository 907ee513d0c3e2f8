"""The LALR tables of the grammar, kept between runs as JSON (never a pickle).

Why: building the tables costs 150-300 ms at every start (``eacc check`` included); loading them
costs about 20 ms. lark's own cache is a pickle, and unpickling a file from disk runs whatever it
says. Here the tables are plain JSON, loaded only from a private file (see ``grace_dsl.cache``)
whose embedded sha256 matches its content; lark rebuilds its objects from that data with a fixed
set of classes. Any doubt (missing, foreign, corrupted, other lark version) rebuilds and rewrites.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

import lark
from lark import Lark
from lark.grammar import Rule
from lark.lark import _LOAD_ALLOWED_OPTIONS
from lark.lexer import TerminalDef

from grace_dsl.cache import cache_dir, untrusted_reason

_FORMAT = 1


def cached_lark(grammar: str, runtime: dict[str, Any], **options: Any) -> Lark:
    """``Lark(grammar, **runtime, **options)``, its tables read from the cache when they can be.

    ``runtime`` holds the objects that cannot be stored (transformer, postlex); ``options`` the
    ones that shape the tables and hence the cache key.
    """
    key = f"{_FORMAT}\0{lark.__version__}\0{sorted(options.items())!r}\0{grammar}"
    path = cache_dir() / "grammar" / f"eac-{hashlib.sha256(key.encode()).hexdigest()[:24]}.json"
    loaded = _load(path, runtime)
    if loaded is not None:
        return loaded
    parser = Lark(grammar, **runtime, **options)
    with contextlib.suppress(OSError, TypeError, ValueError):
        _store(path, parser)
    return parser


def _load(path: Path, runtime: dict[str, Any]) -> Lark | None:
    if not path.is_file() or untrusted_reason(path) is not None:
        return None
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
        tables = stored["tables"]
        if stored["sha256"] != _digest(tables):
            return None
        data = _decode(json.loads(tables))
        return Lark._load_from_dict(data["data"], data["memo"], **runtime)
    except Exception:  # noqa: BLE001 - any failure to read the tables means: rebuild them
        return None


def _store(path: Path, parser: Lark) -> None:
    data, memo = parser.memo_serialize([TerminalDef, Rule])
    data["options"] = {k: v for k, v in data["options"].items() if k not in _LOAD_ALLOWED_OPTIONS}
    tables = json.dumps(_encode({"data": data, "memo": memo}), separators=(",", ":"))
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".grammar-", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump({"sha256": _digest(tables), "tables": tables}, fh)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def _encode(obj: Any) -> Any:
    """JSON for lark's serialized data: tuples and dicts with non-string keys are tagged."""
    if isinstance(obj, dict):
        if all(type(k) is str for k in obj) and not {"__t", "__d"} & obj.keys():
            return {k: _encode(v) for k, v in obj.items()}
        return {"__d": [[_encode(k), _encode(v)] for k, v in obj.items()]}
    if isinstance(obj, tuple):
        return {"__t": [_encode(v) for v in obj]}
    if isinstance(obj, list):
        return [_encode(v) for v in obj]
    if obj is None or type(obj) in (str, int, float, bool):
        return obj
    raise TypeError(f"cannot store {type(obj).__name__} in the grammar cache")


def _decode(obj: Any) -> Any:
    if isinstance(obj, dict):
        if "__t" in obj:
            return tuple(_decode(v) for v in obj["__t"])
        if "__d" in obj:
            return {_decode(k): _decode(v) for k, v in obj["__d"]}
        return {k: _decode(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_decode(v) for v in obj]
    return obj
