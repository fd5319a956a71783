"""The `fabkit` command line: one command, one module per subcommand.

Each subcommand lives in `fabkit/commands/<name>.py` and provides `HELP`, `add_arguments(parser)`
and `run(args) -> int`. Command modules import heavy packages (`robot`, `sim`, mujoco, ur_rtde)
inside `run`, so `fabkit --help` stays fast and `fabkit/` never imports them at module level.

Exit codes: 0 success; 1 ran but missed a tolerance or a check failed; 2 bad input or usage
(one line naming the file and the problem, no traceback); 3 internal error (a bug: set
FABKIT_DEBUG=1 for the traceback).
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from fabkit.errors import InputError, ToleranceError

# name -> one-line summary, in pipeline order (the design's command contract).
COMMANDS: dict[str, str] = {
    "demo": "run the whole pipeline on the built-in tri-fold panel",
    "generate": "procedural input meshes (trifold, reflect, ...)",
    "info": "measure a mesh or FOLD file (angle defect, planarity, tags) and validate it",
    "materials": "sheet materials: list, validate, calibrate springback from test folds",
    "relax": "dynamic relaxation toward zero angle defect and planar faces",
    "unfold": "planar development with error metrics and cut files",
    "panels": "multi-panel workflow: panelise, relax, unfold, congruency, merge",
    "refold": "sequential fold states from flat to target as a FOLD animation",
    "toolpath": "TCP poses, joint solutions, motion parameters and URScript",
    "check": "MuJoCo check of every waypoint and the motion between them",
    "send": "send a checked toolpath to a UR controller over RTDE",
    "ursim": "run the controller stand-in (RTDE, dashboard, script ports) in the foreground",
}

EXIT_OK, EXIT_TOLERANCE, EXIT_INPUT, EXIT_INTERNAL = 0, 1, 2, 3


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one line and exit 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _load(name: str):
    try:
        return importlib.import_module(f"fabkit.commands.{name}")
    except ModuleNotFoundError as exc:
        if exc.name == f"fabkit.commands.{name}":
            return None
        raise


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The full parser; with `only`, just that subcommand's module is imported (fast start-up)."""
    parser = _Parser(
        prog="fabkit",
        description="Curved-crease folded panels: from a coarse mesh to a checked UR robot fold program.",
        epilog="Exit codes: 0 ok, 1 tolerance or check missed, 2 bad input or usage, 3 internal error.",
    )
    from fabkit import __version__

    parser.add_argument("--version", action="version", version=f"fabkit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, summary in COMMANDS.items():
        if only is not None and name != only:
            sub.add_parser(name, help=summary, add_help=False)  # listed in --help, never parsed
            continue
        module = _load(name)
        if module is None:
            p = sub.add_parser(name, help=f"{summary} [not built yet]", description=f"{summary}. Not built yet.")
            p.set_defaults(_run=_not_built(name))
            continue
        p = sub.add_parser(name, help=summary, description=getattr(module, "HELP", summary),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def _not_built(name: str):
    def run(args) -> int:
        print(f"fabkit {name}: error: this subcommand is not built yet", file=sys.stderr)
        return EXIT_INPUT

    return run


def _chosen_command(argv: list[str]) -> str | None:
    """The subcommand named on the command line (first non-option word), if it is one of ours."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    chosen = _chosen_command(argv)
    parser = build_parser(only=chosen if chosen is not None else "")
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_INPUT
    prog = f"fabkit {args.command}"
    try:
        return int(args._run(args) or 0)
    except InputError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except ToleranceError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return EXIT_TOLERANCE
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`fabkit info x.obj | head`): not an error; silence the flush at exit
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except Exception as exc:  # a bug, not the user's fault: say so in one line
        if os.environ.get("FABKIT_DEBUG"):
            raise
        print(f"{prog}: internal error: {type(exc).__name__}: {exc} (FABKIT_DEBUG=1 shows the traceback)",
              file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
