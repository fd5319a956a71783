"""`fabkit ursim`: run the UR controller stand-in in the foreground. A thin caller: the options,
their checks and the run live in `sim.ursim.cli` (imported lazily, as fabkit's layering asks)."""
from __future__ import annotations


def __getattr__(name: str):
    if name == "HELP":  # read by fabkit/cli.py when it builds this subcommand's parser
        from sim.ursim.cli import HELP

        return HELP
    raise AttributeError(name)


def add_arguments(parser) -> None:
    from sim.ursim.cli import add_arguments as add

    add(parser)


def plan_files(args, plan) -> None:
    plan.input(args.cell, "--cell")
    plan.stream(args.log, "--log")
    plan.output(args.report, "--report")


def run(args) -> int:
    from sim.ursim.cli import run_stand_in

    return run_stand_in(args)
