"""A panel with one 0.6 m crease (the load check's acceptance case), through the user's commands."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CELL = str(ROOT / "cells" / "ur5e_bench.toml")
# a 0.6 m crease on a nearly straight arc (radius 5 m, 6.88 deg), folded 45 deg on the UR5e bench
PANEL = ["--radius", "5", "--arc", "6.88", "--fold", "45", "--columns", "12"]
# a light gripper (0.5 kg): the grooved crease's fold force plus the payload's weight stays within
# the UR5e's 49 N and the 50 mm cup's 47 N at this grip
TOOL = ["--tool-mass", "0.5"]
GROOVED = ["--material", "5052-H32", "--thickness", "1mm", "--crease", "grooved", "--ligament", "0.4mm"]


def crease_600_fold(d: Path) -> Path:
    """generate reflect -> unfold -> refold (5 states) into folder `d`; the FOLD file."""
    from fabkit.cli import main as fabkit_main

    for argv in (["generate", "reflect", "-o", str(d / "panel.obj"), "-q", *PANEL],
                 ["unfold", str(d / "panel.obj"), "-o", str(d / "flat.obj"), "-q"],
                 ["refold", str(d / "flat.obj"), str(d / "panel.obj"), "-o", str(d / "seq.fold"), "-q",
                  "--frames", "5"]):
        assert fabkit_main(argv) == 0, argv
    return d / "seq.fold"


def plan(fold: Path, out: Path, *sheet: str) -> Path:
    """`fabkit toolpath` of `fold` on the UR5e bench with the light gripper and `sheet` options."""
    from fabkit.cli import main as fabkit_main

    assert fabkit_main(["toolpath", str(fold), "--cell", CELL, "-o", str(out), "-q", *TOOL, *sheet]) == 0
    return out
