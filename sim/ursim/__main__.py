"""`python -m sim.ursim --host 127.0.0.x [--cell CELL.toml]`: the controller stand-in (as `fabkit ursim`)."""
import argparse
import sys

from fabkit.commands import ursim
from fabkit.errors import InputError


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sim.ursim", description=ursim.HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    ursim.add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return ursim.run(args)
    except InputError as exc:
        print(f"python -m sim.ursim: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
