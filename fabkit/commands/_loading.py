"""The `--units` option and the one way commands read a panel (`fabkit.io.load`), notes printed."""
from __future__ import annotations

import sys

from fabkit.io.units import UNITS


def add_units(parser) -> None:
    """Add `--units m|mm|cm|in` (the unit of an input that does not declare one)."""
    parser.add_argument("--units", choices=tuple(UNITS), default=None,
                        help="unit of the input coordinates when the file does not say (default: the file's "
                             "unit, else metres, with a note when the size suggests another unit)")


def print_notes(args, info) -> None:
    """Each loader note as one line on stderr (also with --quiet: a note can change the result)."""
    for note in info.notes:
        print(f"fabkit {args.command}: note: {info.path}: {note}", file=sys.stderr)


def load_panel_for(args, path, state: str = "folded"):
    """`fabkit.io.load.load_panel` with the command's --units; notes printed -> (mesh, info)."""
    from fabkit.io.load import load_panel

    mesh, info = load_panel(path, getattr(args, "units", None), state=state)
    print_notes(args, info)
    return mesh, info


def load_fold_for(args, path):
    """`fabkit.io.load.load_fold_model` with the command's --units; notes printed -> (model, info)."""
    from fabkit.io.load import load_fold_model

    model, info = load_fold_model(path, getattr(args, "units", None))
    print_notes(args, info)
    return model, info
