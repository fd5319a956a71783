"""Shared by the CLI contract tests: real pipeline inputs, an in-process runner, folder snapshots."""
from __future__ import annotations

import contextlib
import hashlib
import io
import shutil
from pathlib import Path

from fabkit.cli import main
from fabkit.io.atomic import is_temp_name

ROOT = Path(__file__).resolve().parents[1]
CELL_SRC = ROOT / "cells" / "ur5e_bench.toml"


def make_inputs(d: Path) -> Path:
    """The small demo's files (OBJ, FOLD, PATH.json, CHECK.json ...), a canopy low-poly and a cell copy."""
    code, err = run(["demo", "--out", str(d), "--small", "--no-render", "--no-dry-run", "-q"])
    assert code == 0, err
    assert run(["generate", "canopy", "-o", str(d / "canopy.obj"), "-q"])[0] == 0
    shutil.copy(CELL_SRC, d / "cell.toml")
    return d


def run(argv: list[str], fsize: int | None = None) -> tuple[int, str]:
    """`fabkit.cli.main(argv)` in-process -> (exit code, stderr); `fsize`: with the file-size limit
    lowered to that many bytes (a full disk: writes fail with EFBIG, Python ignores SIGXFSZ)."""
    import resource

    err, out = io.StringIO(), io.StringIO()
    saved = resource.getrlimit(resource.RLIMIT_FSIZE)
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            if fsize is not None:
                resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, saved[1]))
            code = main(argv)
        except SystemExit as exc:
            code = int(exc.code or 0)
        finally:
            resource.setrlimit(resource.RLIMIT_FSIZE, saved)
    return code, err.getvalue()


def snapshot(*dirs: Path) -> dict:
    """path -> sha256 (or "dir") of everything under `dirs`."""
    out = {}
    for d in dirs:
        for p in sorted(d.rglob("*")):
            out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
    return out


def temp_files(*dirs: Path) -> list[str]:
    return [str(p) for d in dirs for p in d.rglob("*") if is_temp_name(p.name)]
