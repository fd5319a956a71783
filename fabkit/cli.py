"""The `fabkit` command line: one command, one module per subcommand.

Each subcommand lives in `fabkit/commands/<name>.py` and provides `HELP`, `add_arguments(parser)`,
`plan_files(args, plan)` (declares its input and output files) and `run(args) -> int`. Every run
goes through one output plan (`fabkit.commands._outputs`): files checked before any work, outputs
written to temporary siblings and renamed together after `run` returns, or removed on an error,
Ctrl-C or SIGTERM. Command modules import heavy packages (`robot`, `sim`, mujoco, ur_rtde)
inside `run`, so `fabkit --help` stays fast and `fabkit/` never imports them at module level.

Exit codes: 0 success; 1 ran but missed a tolerance or a check failed; 2 bad input or usage
(one line naming the file and the problem, no traceback); 3 internal error (a bug: set
FABKIT_DEBUG=1 for the traceback).
"""
from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import os
import signal
import sys
import threading

from fabkit.errors import InputError, ToleranceError

# name -> one-line summary, in pipeline order (the design's command contract).
COMMANDS: dict[str, str] = {
    "demo": "run the whole pipeline on the built-in tri-fold panel",
    "generate": "procedural input meshes (trifold, reflect, ...)",
    "info": "measure a mesh or FOLD file (angle defect, planarity, tags) and validate it",
    "tag": "write the panel structure (creases, strips, middle row) as editable # fabkit tags",
    "materials": "sheet materials: list, validate, calibrate springback from test folds",
    "relax": "dynamic relaxation toward zero angle defect and planar faces",
    "unfold": "planar development with error metrics and cut files",
    "panels": "multi-panel workflow: panelise, relax, unfold, congruency, merge",
    "refold": "sequential fold states from flat to target as a FOLD animation",
    "toolpath": "TCP poses, joint solutions, motion parameters and URScript",
    "check": "MuJoCo check of every waypoint and the motion between them",
    "send": "send a checked toolpath to a UR controller over RTDE",
    "ursim": "run the controller stand-in (RTDE, dashboard, script ports) in the foreground",
    "cell": "write a robot cell as a MuJoCo MJCF file",
    "report": "report.html for any run folder from its stages' JSON reports",
}

EXIT_OK, EXIT_TOLERANCE, EXIT_INPUT, EXIT_INTERNAL = 0, 1, 2, 3


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one line and exit 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


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
        module = importlib.import_module(f"fabkit.commands.{name}")
        p = sub.add_parser(name, help=summary, description=getattr(module, "HELP", summary),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
        p.set_defaults(_run=module.run, _plan_files=module.plan_files)
    return parser


class Terminated(Exception):
    """SIGTERM or SIGHUP arrived: unwind (outputs removed, workers stopped) and exit 128 + signal."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


def _raise_terminated(signum, frame):
    raise Terminated(signum)


@contextlib.contextmanager
def _terminate_by_unwinding():
    """SIGTERM/SIGHUP raise `Terminated` in the main thread, so every cleanup runs (once, outermost)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) in (signal.SIG_DFL, None):
            saved[sig] = signal.signal(sig, _raise_terminated)
    try:
        yield
    finally:
        for sig, old in saved.items():
            signal.signal(sig, old)


def _chosen_command(argv: list[str]) -> str | None:
    """The subcommand named on the command line (first non-option word), if it is one of ours."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


#: BLAS/OpenMP thread counts a command runs with unless the user set them: fabkit's matrices are
#: small to medium (a holds check's 777 x 324 SVD), where extra BLAS threads only wait on each other
#: (measured on 2 loaded cores: a two-crease panel's `fabkit toolpath` took 25-35 s of CPU with
#: OpenBLAS's default threads and 9-10 s with one). More cores are used by processes (`--jobs`).
BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _one_blas_thread() -> None:
    """One BLAS thread, unless the user chose: as environment variables, read when numpy loads (not
    yet, for a command run from the shell: the CLI imports it lazily) and by subprocesses; a
    process that loaded numpy already (a script calling `main`) is limited through threadpoolctl."""
    if any(name in os.environ for name in BLAS_THREADS):
        return
    os.environ.update(BLAS_THREADS)
    if "numpy" in sys.modules:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    _one_blas_thread()
    chosen = _chosen_command(argv)
    parser = build_parser(only=chosen if chosen is not None else "")
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_INPUT
    prog = f"fabkit {args.command}"
    from fabkit.commands._outputs import OutputPlan

    plan = OutputPlan(prog)
    try:
        with _terminate_by_unwinding():
            try:
                args._plan_files(args, plan)
                plan.prepare()
                code = int(args._run(args) or 0)
                plan.commit()
            finally:
                plan.abort()  # nothing left when run raised; a no-op after commit
        return code
    except Terminated as exc:
        print(f"{prog}: terminated by {exc}; outputs discarded", file=sys.stderr)
        return 128 + exc.signum
    except InputError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except ToleranceError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return EXIT_TOLERANCE
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; outputs discarded", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`fabkit info x.obj | head`): not an error; silence the flush at exit
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except OSError as exc:
        if os.environ.get("FABKIT_DEBUG") or exc.errno not in _ENVIRONMENT_ERRNOS:
            return _internal(prog, exc)
        where = exc.filename or "file system"
        print(f"{prog}: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_INPUT
    except Exception as exc:  # a bug, not the user's fault: say so in one line
        return _internal(prog, exc)


#: OS errors that are the machine's or the user's doing (full disk, permissions, a folder removed
#: while running), not fabkit's: exit 2 with the path
_ENVIRONMENT_ERRNOS = {errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                       errno.ENAMETOOLONG, errno.EIO, errno.ENOENT, errno.ENOTDIR, errno.EMFILE}


def _internal(prog: str, exc: BaseException) -> int:
    if os.environ.get("FABKIT_DEBUG"):
        raise exc
    print(f"{prog}: internal error: {type(exc).__name__}: {exc} (FABKIT_DEBUG=1 shows the traceback)",
          file=sys.stderr)
    return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
