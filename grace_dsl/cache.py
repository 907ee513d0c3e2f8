"""The one cache directory of grace_dsl, and the rule that decides whether to trust what is in it.

Why a rule: the cache holds native libraries that are ``dlopen``ed and CasADi functions that are
deserialized (a serialized CasADi function may name a library to load). Whoever can write there
runs code as the user. So, like ssh with its keys, a file is trusted only when it and every
directory above it are owned by the user (or root) and not writable by group or others (a sticky
directory such as ``/tmp`` is fine: others cannot rename or delete what is in it). Digests protect
against corruption; ownership and mode are the trust root.
"""

from __future__ import annotations

import atexit
import os
import shutil
import stat
import tempfile
from pathlib import Path

import platformdirs

__all__ = ["build_dir", "cache_dir", "existing_private_dir", "private_dir", "untrusted_reason"]


def cache_dir() -> Path:
    """The cache root: ``$GRACE_CACHE_DIR``, else the per-user cache (``~/.cache/grace-dsl``).

    Builds live in ``build/``, stand-alone native kernels in ``native/`` and the parser's tables
    in ``grammar/``, all under this one root.
    """
    env = os.environ.get("GRACE_CACHE_DIR")
    return Path(env) if env else Path(platformdirs.user_cache_dir("grace-dsl"))


def build_dir() -> Path:
    """Where compiled units live by default."""
    return cache_dir() / "build"


def untrusted_reason(path: Path) -> str | None:
    """Why ``path`` must not be loaded as code or deserialized, or None when it may.

    ``path`` and each directory above it must be owned by this user or root and must not be
    writable by group or others, unless it is a sticky directory.
    """
    uid = os.geteuid()
    try:
        current = path.resolve(strict=True)
    except (OSError, RuntimeError) as exc:
        return f"{path} cannot be resolved ({exc})"
    for part in (current, *current.parents):
        try:
            st = os.stat(part)
        except OSError as exc:
            return f"{part} cannot be inspected ({exc.strerror})"
        if st.st_uid not in (uid, 0):
            return f"{part} is owned by uid {st.st_uid}, not by you"
        sticky_dir = stat.S_ISDIR(st.st_mode) and st.st_mode & stat.S_ISVTX
        if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH) and not sticky_dir:
            return f"{part} is writable by {'others' if st.st_mode & stat.S_IWOTH else 'its group'}"
    return None


def private_dir(name: str) -> Path:
    """A directory only this user can write, reused across runs: ``$TMPDIR/grace-dsl-<uid>/name``.

    When that place is taken by someone else, a fresh private temporary directory that is removed
    at exit (never a trail of ``grace-dsl-cache-*`` directories).
    """
    base = _private_base()
    try:
        base.mkdir(mode=0o700, exist_ok=True)
        target = base / name
        target.mkdir(mode=0o700, exist_ok=True)
        if untrusted_reason(target) is None:
            return target
    except OSError:
        pass
    fresh = Path(tempfile.mkdtemp(prefix="grace-dsl-"))
    atexit.register(shutil.rmtree, fresh, True)
    return fresh


def existing_private_dir(name: str) -> Path | None:
    """:func:`private_dir` if an earlier run made it (and it is still private); never creates."""
    target = _private_base() / name
    return target if target.is_dir() and untrusted_reason(target) is None else None


def _private_base() -> Path:
    return Path(tempfile.gettempdir()) / f"grace-dsl-{os.geteuid()}"
