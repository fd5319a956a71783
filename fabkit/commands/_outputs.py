"""The output plan every subcommand runs through: all files declared and checked before any work,
all outputs committed together at the end or not at all.

Each command module has `plan_files(args, plan)` that declares its inputs and outputs; the CLI
then calls `prepare()` before `run(args)` and `commit()` after it (`abort()` on any exception or
signal). `prepare()` refuses, with one line naming the path (an `OutputError`, exit 2):

- an input that exists but is not a regular file (a folder, FIFO, device such as /dev/zero);
- an output that is the same file as an input or as another output: same path, same path after
  symlinks, same inode (hard links), or names that differ only in case in a case-insensitive folder;
- an output whose name is longer than the file system allows, whose folder is missing or not
  writable, that is an existing folder (or, for a folder output, an existing file), or read-only.

It then reserves one temporary sibling per output (`fabkit.io.atomic.StagedWrites`), which proves
the folder writable, and removes temporary files left there by killed fabkit processes.
"""
from __future__ import annotations

import contextlib
import os
import stat
from dataclasses import dataclass
from pathlib import Path

from fabkit.errors import OutputError
from fabkit.io.atomic import StagedWrites, clean_stale, name_max, temp_sibling, write_error

__all__ = ["OutputPlan"]

# kinds of output
FILE = "file"  # staged: written to a temporary sibling, renamed at commit
FOLDER = "folder"  # staged folder: built as a temporary sibling folder, merged in at commit
WORKDIR = "workdir"  # a folder created up front whose files come from their own plans (demo)
STREAM = "stream"  # written as the command goes (a log): checked up front, not staged


@dataclass(frozen=True)
class _Entry:
    path: Path
    option: str
    kind: str = FILE


class OutputPlan:
    """Inputs and outputs of one command run (see the module docstring)."""

    def __init__(self, prog: str = "fabkit") -> None:
        self.prog = prog
        self.inputs: list[_Entry] = []
        self.outputs: list[_Entry] = []
        self._staged: StagedWrites | None = None
        self._created: list[Path] = []

    # -- declaration (None and "" are ignored, lists are flattened) --------------------------
    def input(self, path, option: str) -> None:
        for p in _paths(path, option):
            self.inputs.append(_Entry(Path(p), option))

    def output(self, path, option: str) -> None:
        for p in _paths(path, option):
            self.outputs.append(_Entry(Path(p), option, FILE))

    def folder(self, path, option: str) -> None:
        """A folder output written all at once (its files appear together at commit)."""
        for p in _paths(path, option):
            self.outputs.append(_Entry(Path(p), option, FOLDER))

    def workdir(self, path, option: str) -> None:
        """A folder created up front (removed again if the run fails and it is still empty)."""
        for p in _paths(path, option):
            self.outputs.append(_Entry(Path(p), option, WORKDIR))

    def stream(self, path, option: str) -> None:
        """A file written while the command runs (a log): checked up front, kept as far as it got."""
        for p in _paths(path, option):
            self.outputs.append(_Entry(Path(p), option, STREAM))

    # -- the checks ---------------------------------------------------------------------------
    def prepare(self) -> None:
        """Check everything, then reserve the temporary files; raises `OutputError` (nothing left)."""
        for e in self.inputs:
            _check_input(e)
        pending = {os.path.realpath(e.path) for e in self.outputs if e.kind == WORKDIR and not e.path.is_dir()}
        for e in self.outputs:
            if os.path.realpath(_parent(e.path)) in pending:
                continue  # a file in a work folder this run creates: the folder's check covers it
            _check_output(e)
        self._check_clashes()
        staged = StagedWrites()
        try:
            for e in self.outputs:
                try:
                    if e.kind == FILE:
                        staged.add_file(e.path)
                    elif e.kind == FOLDER:
                        staged.add_folder(e.path)
                    elif e.kind == STREAM:
                        _probe(e.path)
                    elif not e.path.is_dir():
                        e.path.mkdir(parents=True)
                        self._created.append(e.path)
                except OSError as exc:
                    raise write_error(exc, e.path) from None
            for folder in {_parent(e.path) for e in self.outputs}:
                clean_stale(folder)
        except BaseException:
            staged.abort()
            self._remove_created()
            raise
        self._staged = staged.__enter__()

    def _check_clashes(self) -> None:
        seen: list[tuple[_Entry, str]] = []
        for e in self.inputs:
            seen.append((e, "input"))
        for e in self.outputs:
            for other, role in seen:
                if _same_file(e.path, other.path):
                    if role == "input":
                        raise OutputError(f"an output would overwrite the input ({e.option} is {other.option})",
                                          source=str(e.path))
                    raise OutputError(f"two outputs name the same file ({other.option} and {e.option})",
                                      source=str(e.path))
            seen.append((e, "output"))

    # -- the end ------------------------------------------------------------------------------
    def commit(self) -> None:
        if self._staged is not None:
            staged, self._staged = self._staged, None
            try:
                staged.commit()
            except OSError as exc:
                raise write_error(exc, exc.filename or "output") from None
            finally:
                staged.__exit__(None, None, None)
        self._created = []

    def abort(self) -> None:
        if self._staged is not None:
            staged, self._staged = self._staged, None
            staged.__exit__(None, None, None)
        self._remove_created()

    def _remove_created(self) -> None:
        for p in reversed(self._created):
            with contextlib.suppress(OSError):
                p.rmdir()  # only when still empty
        self._created = []


def _paths(path, option: str = "output") -> list[str]:
    if path is None:
        return []
    paths = [str(p) for p in path] if isinstance(path, (list, tuple)) else [str(path)]
    if any(not p for p in paths):
        raise OutputError("an empty file name", source=option)
    return paths


def _parent(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def _check_input(e: _Entry) -> None:
    try:
        st = os.stat(e.path)
    except OSError:
        return  # missing or unreadable: the reader says so in its own words
    if stat.S_ISDIR(st.st_mode):
        raise OutputError("is a directory, expected a file", source=str(e.path))
    if not stat.S_ISREG(st.st_mode):
        raise OutputError("is not a regular file (a FIFO, device or socket): refusing to read it",
                          source=str(e.path))


def _check_output(e: _Entry) -> None:
    path = e.path
    name = path.name
    if not name or name in (".", ".."):
        if e.kind in (FILE, STREAM):
            raise OutputError("is a directory, not a file name", source=str(path))
    parent = _parent(path)
    if e.kind == WORKDIR:
        while not parent.exists() and parent != _parent(parent):
            parent = _parent(parent)
    if name and len(os.fsencode(name)) > name_max(parent if parent.is_dir() else "."):
        raise OutputError(f"the file name is {len(os.fsencode(name))} bytes, longer than the "
                          f"{name_max(parent if parent.is_dir() else '.')} the file system allows", source=str(path))
    if not parent.is_dir():
        raise OutputError("output directory does not exist", source=str(path))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write: the folder {parent} is not writable", source=str(path))
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise write_error(exc, path) from None
    if e.kind in (FOLDER, WORKDIR):
        if not stat.S_ISDIR(st.st_mode):
            raise OutputError(f"exists and is not a folder ({e.option} names an output folder)", source=str(path))
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputError("cannot write: the folder is not writable", source=str(path))
        return
    if stat.S_ISDIR(st.st_mode):
        raise OutputError("is a directory, not a file name", source=str(path))
    if not stat.S_ISREG(st.st_mode):
        raise OutputError("is not a regular file (a FIFO, device or socket): refusing to replace it",
                          source=str(path))
    if not os.access(path, os.W_OK):
        raise OutputError("cannot write: the file is read-only", source=str(path))


def _same_file(a: Path, b: Path) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    with contextlib.suppress(OSError):
        sa, sb = os.stat(a), os.stat(b)
        if (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino):
            return True
    ra, rb = Path(os.path.realpath(a)), Path(os.path.realpath(b))
    if ra.parent == rb.parent and ra.name != rb.name and ra.name.casefold() == rb.name.casefold():
        return _case_insensitive(ra.parent)
    return False


def _case_insensitive(folder: Path) -> bool:
    """True when `folder` ignores case in names (probed with a temporary file)."""
    if not os.access(folder, os.W_OK):
        return False
    probe = temp_sibling(folder / "case-probe")
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError:
        return False
    os.close(fd)
    try:
        return probe.name != probe.name.swapcase() and os.path.exists(probe.with_name(probe.name.swapcase()))
    finally:
        with contextlib.suppress(OSError):
            os.unlink(probe)


def _probe(path: Path) -> None:
    """Prove that a file can be created in `path`'s folder (raises OSError)."""
    tmp = temp_sibling(path)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    os.close(fd)
    os.unlink(tmp)
