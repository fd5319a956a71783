"""Options and helpers every subcommand shares: --report, --quiet, progress, JSON reports."""
from __future__ import annotations

import contextlib
import sys
from typing import Any, Iterator



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


def write_report(args, data: dict) -> None:
    if getattr(args, "report", None):
        write_json(args.report, data)


def to_jsonable(obj: Any) -> Any:
    """`fabkit.io.jsonfile.to_jsonable`, imported on use (keeps `fabkit SUB --help` free of numpy)."""
    from fabkit.io.jsonfile import to_jsonable as convert

    return convert(obj)


def write_json(path, data: Any) -> None:
    """`fabkit.io.jsonfile.write_json`, imported on use."""
    from fabkit.io.jsonfile import write_json as write

    write(path, data)
