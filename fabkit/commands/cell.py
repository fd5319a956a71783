"""`fabkit cell CELL.toml --mjcf F.xml`: the robot cell as a MuJoCo MJCF file other tools open."""
from __future__ import annotations

from fabkit.commands._common import add_common, say, write_report

HELP = """Build the MuJoCo model of a robot cell (the one `fabkit check` uses: arm, tool, fixture,
obstacles, limits) and write it as MJCF XML, so it opens in MuJoCo's viewer (`python -m
mujoco.viewer --mjcf F.xml`) or any MJCF tool. The file is read back with
mujoco.MjModel.from_xml_path before it is kept; it holds the cell without a panel.

Exit codes: 0 written; 2 bad cell file or output path.

example:
  fabkit cell cells/ur5e_bench.toml --mjcf ur5e_bench.xml
"""


def add_arguments(parser) -> None:
    parser.add_argument("cell", metavar="CELL.toml", help="robot cell description")
    parser.add_argument("--mjcf", metavar="F.xml", required=True, help="write the cell as MuJoCo MJCF XML")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.cell, "CELL.toml")
    plan.output(args.mjcf, "--mjcf")
    plan.output(getattr(args, "report", None), "--report")


def run(args) -> int:
    from pathlib import Path

    import mujoco

    from fabkit.errors import InputError
    from fabkit.io.atomic import atomic_path
    from robot.cell import load_cell
    from sim.model import build_cell_model

    if not str(args.mjcf).lower().endswith(".xml"):
        raise InputError("MJCF is written as .xml", source=args.mjcf)
    cell = load_cell(args.cell)
    model, names = build_cell_model(cell)
    xml = names.spec.to_xml()
    with atomic_path(args.mjcf) as tmp:
        Path(tmp).write_text(xml, encoding="utf-8")
        back = mujoco.MjModel.from_xml_path(str(tmp))  # what other tools will load
        if (back.nbody, back.ngeom, back.njnt) != (model.nbody, model.ngeom, model.njnt):
            raise RuntimeError(f"MJCF reads back with {back.nbody} bodies, {back.ngeom} geoms, {back.njnt} joints; "
                               f"the model has {model.nbody}, {model.ngeom}, {model.njnt}")
    report = {"command": "cell", "cell": cell.name, "robot": cell.model.name, "mjcf": str(args.mjcf),
              "unit": "m", "bodies": int(model.nbody), "geoms": int(model.ngeom), "joints": int(model.njnt)}
    write_report(args, report)
    say(args, f"{args.mjcf}: MJCF of cell {cell.name} ({cell.model.name}): {model.nbody} bodies, {model.ngeom} geoms, "
              f"{model.njnt} joints (metres, radians)")
    return 0
