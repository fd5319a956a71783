"""Write-then-rename so no command ever leaves a half-written output file behind.

Every temporary file is a hidden sibling of its target named `.NAME.fabkit-<pid>-<token>.tmp[.ext]`
(the target's extension kept, so writers that pick a format from the name still work), so a file
left by a killed process is recognisable: `clean_stale(folder)` removes those whose process is gone.

`StagedWrites` is the all-or-nothing form: it reserves one temporary file (or folder) per target
up front; while it is active, `atomic_write` / `atomic_path` on a staged target write its
temporary file and leave the rename to `commit()`, which renames every written target at the end
(`abort()` removes them all instead). A write error (full disk, file-size limit, read-only folder)
is an `OutputError` naming the target, never a bare `OSError`.
"""
from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Iterator

from fabkit.errors import InputError, OutputError

__all__ = ["atomic_write", "atomic_path", "StagedWrites", "clean_stale", "temp_sibling", "staging_path",
           "written_path", "name_max", "is_temp_name", "write_error"]

#: `.NAME.fabkit-<pid>-<token>.tmp` (+ the target's extension); also matches staging folders inside
TEMP_NAME = re.compile(r"^\..*?\.fabkit-(\d+)-[0-9a-f]+\.tmp(?:\.|$)")

_stages: list["StagedWrites"] = []


def _file_mode() -> int:
    """The mode a plainly created file gets (0o666 minus the umask); mkstemp would give 0o600."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def name_max(directory: str | os.PathLike) -> int:
    """Longest file name (bytes) the file system of `directory` allows (255 on ext4, tmpfs, xfs)."""
    try:
        return int(os.pathconf(directory, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def is_temp_name(name: str) -> bool:
    return TEMP_NAME.match(name) is not None


def temp_sibling(path: str | os.PathLike) -> Path:
    """A fresh temporary name next to `path`, shortened to fit the file system's name limit."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    suffix = path.suffix if len(path.suffix) <= 16 else ""
    tail = f".fabkit-{os.getpid()}-{secrets.token_hex(4)}.tmp{suffix}"
    head = "." + path.name
    limit = name_max(directory)
    while head and len(os.fsencode(head + tail)) > limit:
        head = head[:-1]
    return directory / ((head or ".") + tail)


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def clean_stale(directory: str | os.PathLike) -> list[Path]:
    """Remove fabkit temporary files and folders in `directory` whose writing process is dead."""
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(directory):
            m = TEMP_NAME.match(entry.name)
            if m is None or _pid_alive(int(m.group(1))):
                continue
            with contextlib.suppress(OSError):
                if entry.is_dir(follow_symlinks=False):
                    shutil.rmtree(entry.path)
                else:
                    os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


def write_error(exc: OSError, target: str | os.PathLike) -> OutputError:
    """The one-line refusal for an OS error met while writing `target`."""
    why = {errno.ENOSPC: "the disk is full", errno.EFBIG: "the file is larger than the file-size limit",
           errno.EDQUOT: "the disk quota is exceeded", errno.EROFS: "the file system is read-only",
           errno.EACCES: "permission denied", errno.EPERM: "permission denied",
           errno.ENAMETOOLONG: "the file name is too long"}.get(exc.errno, exc.strerror or str(exc))
    return OutputError(f"cannot write: {why}", source=str(target))


def _create_empty(tmp: Path) -> None:
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, _file_mode())
    os.close(fd)


def _directory_of(path: Path) -> Path:
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise InputError("output directory does not exist", source=str(path))
    return directory


@dataclass
class _Staged:
    target: Path
    temp: Path
    folder: bool = False
    written: bool = False


def _key(path: str | os.PathLike) -> str:
    return os.path.realpath(os.fspath(path))


class StagedWrites:
    """Targets written to reserved temporary siblings and renamed over their targets together."""

    def __init__(self) -> None:
        self._items: dict[str, _Staged] = {}

    # -- reservation (raises OSError: the caller names the option) -------------------------------
    def add_file(self, target: str | os.PathLike) -> Path:
        tmp = temp_sibling(target)
        _create_empty(tmp)
        self._items[_key(target)] = _Staged(Path(target), tmp)
        return tmp

    def add_folder(self, target: str | os.PathLike) -> Path:
        tmp = temp_sibling(Path(target).with_suffix("") if Path(target).suffix else target)
        os.mkdir(tmp)
        self._items[_key(target)] = _Staged(Path(target), tmp, folder=True)
        return tmp

    def temps(self) -> list[Path]:
        return [s.temp for s in self._items.values()]

    # -- activity ------------------------------------------------------------------------------
    def __enter__(self) -> "StagedWrites":
        _stages.append(self)
        return self

    def __exit__(self, *exc) -> None:
        if self in _stages:
            _stages.remove(self)
        self.abort()  # a no-op after commit()

    def lookup(self, path: str | os.PathLike) -> tuple[Path, _Staged] | None:
        """(where to write, staged item) for a staged file or a path inside a staged folder."""
        key = _key(path)
        item = self._items.get(key)
        if item is not None:
            return item.temp, item
        for k, it in self._items.items():
            if it.folder and key.startswith(k + os.sep):
                return it.temp / os.path.relpath(key, k), it
        return None

    def commit(self) -> None:
        """Rename every written target into place (folders merged file by file); drop the rest."""
        items, self._items = list(self._items.values()), {}
        try:
            for it in items:
                if not it.written:
                    continue
                if it.folder:
                    _merge_folder(it.temp, it.target)
                else:
                    os.replace(it.temp, it.target)
        finally:
            _remove(items)

    def abort(self) -> None:
        items, self._items = list(self._items.values()), {}
        _remove(items)


def _remove(items) -> None:
    for it in items:
        with contextlib.suppress(OSError):
            if it.folder:
                shutil.rmtree(it.temp)
            else:
                os.unlink(it.temp)


def _merge_folder(src: Path, dst: Path) -> None:
    if not dst.exists():
        os.rename(src, dst)
        return
    for root, dirs, files in os.walk(src):
        rel = os.path.relpath(root, src)
        out = dst / rel if rel != "." else dst
        out.mkdir(exist_ok=True)
        for f in files:
            os.replace(os.path.join(root, f), out / f)


def _staged(path: Path) -> tuple[Path, _Staged] | None:
    for stage in reversed(_stages):
        hit = stage.lookup(path)
        if hit is not None:
            return hit
    return None


def staging_path(path: str | os.PathLike) -> Path:
    """Where a writer that moves files itself should put `path` (its staging folder when staged)."""
    hit = _staged(Path(path))
    if hit is None:
        return Path(path)
    hit[1].written = True
    return hit[0]


def written_path(path: str | os.PathLike) -> Path:
    """Where `path` written earlier in this run is now: its staged file until the stage commits
    (for a step that reads another's output, e.g. the book embedding the sheet pictures)."""
    hit = _staged(Path(path))
    if hit is not None and hit[0].exists():
        return hit[0]
    return Path(path)


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a temporary file next to `path`; on success rename it over `path`, on error delete it.

    Under an active `StagedWrites` that stages `path`, the rename waits for its `commit()`."""
    with atomic_path(path) as tmp:
        binary = "b" in mode
        try:
            with open(tmp, mode, **({} if binary else {"encoding": encoding, "newline": ""})) as fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            raise write_error(exc, path) from None


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path for writers that want a filename (ezdxf, matplotlib, trimesh).

    The file is renamed over `path` only if the block finishes without an exception (under an
    active `StagedWrites` staging `path`: at its `commit()`).
    """
    path = Path(path)
    hit = _staged(path)
    if hit is not None:
        where, item = hit
        if item.folder:  # a file inside a staged folder: an ordinary atomic write there
            where.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(where) as tmp:
                yield tmp
            item.written = True
            return
        try:
            yield where
        except OSError as exc:
            raise write_error(exc, path) from None
        item.written = True
        return
    _directory_of(path)
    tmp = temp_sibling(path)
    try:
        _create_empty(tmp)
    except OSError as exc:
        raise write_error(exc, path) from None
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise write_error(exc, path) from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
