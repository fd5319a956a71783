"""`python -m sim.ursim --host 127.0.0.x [--cell CELL.toml]`: the controller stand-in (as `fabkit ursim`)."""
import argparse
import sys

from fabkit.errors import InputError
from sim.ursim.cli import HELP, add_arguments, run_stand_in

PROG = "python -m sim.ursim"


class _Parser(argparse.ArgumentParser):
    """Usage errors are one line and exit 2 (fabkit's CLI contract)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def main(argv=None) -> int:
    parser = _Parser(prog=PROG, description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run_stand_in(args)
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
