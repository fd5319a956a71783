"""Options and helpers every subcommand shares: --report, --quiet, progress, JSON reports."""
from __future__ import annotations

import contextlib
import json
import math
import sys
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from fabkit.io.atomic import atomic_write


def add_common(parser) -> None:
    """Add `--report FILE` and `--quiet` to a subcommand parser."""
    parser.add_argument("--report", metavar="R.json", help="write a machine-readable JSON report")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar and no summary")


def show_progress(args) -> bool:
    return not getattr(args, "quiet", False) and sys.stderr.isatty()


@contextlib.contextmanager
def progress(args, description: str, total: float | None = None) -> Iterator:
    """A rich progress bar on a terminal, a no-op otherwise. Yields `advance(n=1)`."""
    if not show_progress(args):
        yield lambda n=1, **kw: None
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed:.0f}/{task.total}"),
                  TimeElapsedColumn(), transient=True, console=None) as bar:
        task = bar.add_task(description, total=total)
        yield lambda n=1, **kw: bar.update(task, advance=n, **kw)


def say(args, text: str) -> None:
    """Print a human summary line unless --quiet."""
    if not getattr(args, "quiet", False):
        print(text)


def to_jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays and dataclasses to plain JSON values (NaN/Inf -> None)."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "__dataclass_fields__"):
        import dataclasses

        return to_jsonable(dataclasses.asdict(obj))
    return obj


def write_json(path: str | Path, data: Any) -> None:
    """Write JSON atomically (temporary file + rename)."""
    with atomic_write(path) as fh:
        json.dump(to_jsonable(data), fh, indent=1, allow_nan=False)
        fh.write("\n")


def write_report(args, data: dict) -> None:
    if getattr(args, "report", None):
        write_json(args.report, data)
