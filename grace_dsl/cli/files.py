"""The command line's file handling: which ``.eac`` files a path names, reading a user's file,
and writing one atomically.

Every file the command line writes for a user (``fmt``, ``prompt -o``, ``export``, ``show``)
goes through ``atomic_write``: a full disk, a file-size limit or a crash leaves the old file
whole, never half a new one. Reading refuses what is not a regular file *before* opening it,
so a FIFO named ``x.eac`` cannot block the command.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

from grace_dsl.runtime.errors import GraceError

T = TypeVar("T")

BOM = "\ufeff"


class UserFileError(GraceError):
    """A file the user named that cannot be read or written; the message is one line."""


# ---- what a path is -----------------------------------------------------------------------------


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a regular file"


def file_problem(path: Path) -> str | None:
    """Why ``path`` cannot be read as a regular file (None when it can), without opening it."""
    try:
        st = path.stat()
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "a symlink loop"
        if exc.errno == errno.ENOENT and path.is_symlink():
            return f"a dangling symlink (to {os.readlink(path)})"
        if exc.errno == errno.ENOENT:
            return "no such file"
        return exc.strerror or str(exc)
    if not stat.S_ISREG(st.st_mode):
        return f"{_kind(st.st_mode)}, not a file"
    return None


def symlink_to_other(path: Path) -> str | None:
    """The target of a symlink named ``*.eac`` that points at something else than a ``.eac``
    file (``passwd.eac -> /etc/passwd``): such a file is skipped, never read, so no diagnostic
    can echo its contents."""
    if not path.is_symlink():
        return None
    real = Path(os.path.realpath(path))
    return None if real.suffix == ".eac" else str(real)


@dataclass(frozen=True)
class Skipped:
    """A path found in a directory that is not read, and why."""

    path: str
    reason: str


def eac_files(paths: Sequence[str]) -> tuple[list[str], list[Skipped]]:
    """The ``.eac`` files below directories (sorted, symlinked directories not followed) and the
    files named directly; what cannot be read is returned as skipped instead.

    A file named directly that is missing stays in the list, so the compiler reports it where it
    reports every other file problem; ``-`` (stdin) passes through."""
    files: list[str] = []
    skipped: list[Skipped] = []
    for p in paths:
        path = Path(p)
        if p != "-" and _is_real_dir(path):
            found, bad = _walk(path)
            files += found
            skipped += bad
            continue
        problem = None if p == "-" else file_problem(path)
        if problem is not None and problem != "no such file":
            skipped.append(Skipped(p, problem))
        else:
            files.append(p)
    return files, skipped


def _is_real_dir(path: Path) -> bool:
    """A directory named on the command line is searched even when it is a symlink."""
    try:
        return path.is_dir()
    except OSError:
        return False


def _walk(root: Path) -> tuple[list[str], list[Skipped]]:
    files: list[str] = []
    skipped: list[Skipped] = []
    for here, dirs, names in os.walk(root, followlinks=False):
        dirs.sort()
        for name in sorted(names + [d for d in dirs if os.path.islink(os.path.join(here, d))]):
            if not name.endswith(".eac"):
                continue
            path = Path(here, name)
            problem = file_problem(path)
            target = symlink_to_other(path) if problem is None else None
            if problem is None and target is not None:
                problem = f"a symlink to {target}, which is not a .eac file"
            if problem is None:
                files.append(str(path))
            else:
                skipped.append(Skipped(str(path), problem))
    return files, skipped


# ---- reading ------------------------------------------------------------------------------------


def read_bytes(path: Path) -> bytes:
    """The bytes of a regular file, or a one-line ``UserFileError`` (never blocks on a FIFO)."""
    problem = file_problem(path)
    if problem is not None:
        raise UserFileError(f"{path}: {problem}")
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as f:
            return f.read()
    except OSError as exc:
        raise UserFileError(f"{path}: cannot read: {exc.strerror or exc}") from None


@dataclass(frozen=True)
class Source:
    """A source file's text without its byte-order mark, and whether it had one."""

    text: str
    bom: bool = False


def read_source(path: Path) -> Source:
    """A UTF-8 text file (a leading byte-order mark is accepted, as the compiler does)."""
    data = read_bytes(path)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise UserFileError(
            f"{path}: not UTF-8 text: byte 0x{data[exc.start]:02x} at line {line}, column {col}"
        ) from None
    return Source(text.removeprefix(BOM), text.startswith(BOM))


# ---- writing ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Written:
    """What ``atomic_write`` replaced: nothing (a new file), a file, or a symlink (not followed:
    the link itself is replaced by the new file)."""

    path: Path
    replaced: str  # "" | "file" | "symlink"
    link_target: str = ""

    def note(self) -> str:
        """``"overwrote out.urdf"`` and the like; empty for a new file."""
        if self.replaced == "symlink":
            return f"replaced the symlink {self.path} (to {self.link_target}) by a file"
        return f"overwrote {self.path}" if self.replaced else ""


def atomic_write(
    path: str | Path, data: bytes | str, verify: Callable[[Path], None] | None = None
) -> Written:
    """Write ``data`` to ``path`` so that readers see the old file or the new one, never a
    part: a temporary file in the same directory, fsync, ``verify(temporary)`` (which raises
    to refuse it), rename over ``path``, fsync of the directory. On any failure the temporary
    file is removed and ``path`` is untouched. A symlink at ``path`` is replaced, not followed;
    a file's permission bits are kept."""
    target = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    previous = _previous(target)
    directory = target.parent
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise UserFileError(f"cannot write {target}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(payload)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, previous.mode if previous.replaced == "file" else _default_mode())
        if verify is not None:
            verify(Path(tmp))
        os.replace(tmp, target)
    except BaseException as exc:
        _remove(tmp)
        if isinstance(exc, OSError):
            raise UserFileError(f"cannot write {target}: {exc.strerror or exc}") from None
        raise
    _fsync_dir(directory)
    return Written(target, previous.replaced, previous.link_target)


@dataclass(frozen=True)
class _Previous:
    replaced: str
    link_target: str = ""
    mode: int = 0


def _previous(target: Path) -> _Previous:
    """What is at ``target`` now; a directory is refused (it cannot be replaced by a file)."""
    try:
        st = target.lstat()
    except FileNotFoundError:
        return _Previous("")
    except OSError as exc:
        raise UserFileError(f"cannot write {target}: {exc.strerror or exc}") from None
    if stat.S_ISLNK(st.st_mode):
        return _Previous("symlink", os.readlink(target))
    if stat.S_ISDIR(st.st_mode):
        raise UserFileError(f"cannot write {target}: it is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise UserFileError(f"cannot write {target}: it is {_kind(st.st_mode)}")
    return _Previous("file", mode=stat.S_IMODE(st.st_mode))


def _default_mode() -> int:
    """The mode ``open`` would give a new file (0666 less the umask); mkstemp makes 0600."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def _remove(path: str) -> None:
    with contextlib.suppress(OSError):
        os.unlink(path)


def _fsync_dir(directory: Path) -> None:
    """Make the rename durable; some file systems cannot fsync a directory, which is fine."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def remove_files(paths: Iterable[Path]) -> list[Path]:
    """Remove files (those an export owns and no longer writes); return those removed."""
    removed = []
    for p in paths:
        try:
            p.unlink()
            removed.append(p)
        except FileNotFoundError:
            pass
        except OSError as exc:
            raise UserFileError(f"cannot remove the stale file {p}: {exc.strerror}") from None
    return removed


# ---- outputs written by a library function ------------------------------------------------------


def staged(target: Path, produce: Callable[[Path], T]) -> tuple[T, list[Written]]:
    """Let ``produce(path)`` write ``target`` (and files beside it, such as a mesh directory)
    into a private directory next to it, then move every file into place with ``atomic_write``:
    the files beside first, ``target`` last, so it never names a file that is not there yet.
    Returns what ``produce`` returned and what each write replaced."""
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".staging", dir=parent))
    except OSError as exc:
        raise UserFileError(f"cannot write {target}: {exc.strerror or exc}") from None
    try:
        result = produce(staging / target.name)
        made = sorted(p for p in staging.rglob("*") if p.is_file())
        made.sort(key=lambda p: p.name == target.name and p.parent == staging)
        written = [atomic_write(parent / p.relative_to(staging), p.read_bytes()) for p in made]
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return result, written
