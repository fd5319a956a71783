"""`fabkit materials`: list the sheet materials, validate material files, calibrate springback."""
from __future__ import annotations

import sys
from pathlib import Path

from fabkit.commands._common import add_common, say, write_report

HELP = """List the sheet materials (fabkit/materials/data/*.toml), or validate material files, or
calibrate a material's springback factor from measured test folds.

The table: name, yield stress and UTS [MPa], Young's modulus [GPa], density [kg/m^3], springback
calibration factor, K-factor rule, minimum inside radius of plain creases at 1 mm, the crease
preparations allowed. `none` is the rigid material (no springback, no payload: the design shape).
Use a name or a .toml file with --material on `fabkit toolpath`.

--calibrate FILE fits the springback factor to test folds (FILE: material, thickness_mm, optional
inside_radius_mm / crease / ligament_mm / name, and [[folds]] with programmed_deg and measured_deg;
docs/sheet.md) and writes the calibrated material to -o OUT.toml.

Exit codes: 0 ok; 2 a bad material or calibration file (one line naming the file and the field;
nothing written).

Examples:
  fabkit materials
  fabkit materials --calibrate testfolds.toml -o 5052-H32-shop.toml
  fabkit toolpath seq.fold --cell cells/ur5e_bench.toml -o path.json --material 5052-H32-shop.toml --thickness 1.6mm
"""


def add_arguments(parser) -> None:
    parser.add_argument("files", nargs="*", metavar="MATERIAL.toml",
                        help="validate and list these material files instead of the packaged ones")
    parser.add_argument("--calibrate", metavar="FILE.toml", help="calibration file: measured test folds")
    parser.add_argument("-o", "--output", metavar="OUT.toml", help="with --calibrate: the calibrated material")
    add_common(parser)


def _row(m) -> list[str]:
    from fabkit.errors import InputError
    from fabkit.sheet import minimum_inside_radius

    if m.rigid:
        return [m.name, "-", "-", "-", "-", "-", "-", "-", "rigid: no springback, no mass"]
    try:
        rmin = f"{minimum_inside_radius(m, 1e-3) * 1000:g}"
    except InputError:  # the material's table does not reach down to 1 mm
        rmin = "-"
    kf = m.k_factor if isinstance(m.k_factor, str) else f"{m.k_factor:g}"
    return [m.name, f"{m.yield_stress / 1e6:g}", f"{m.uts / 1e6:g}", f"{m.youngs_modulus / 1e9:g}",
            f"{m.density:g}", f"{m.calibration:g}", kf, rmin, ", ".join(m.preparations)]


def plan_files(args, plan) -> None:
    plan.input(list(args.files), "MATERIAL.toml")
    plan.input(args.calibrate, "--calibrate")
    plan.output(args.output, "-o")
    plan.output(getattr(args, "report", None), "--report")


def run(args) -> int:
    from fabkit.errors import InputError
    from fabkit.io.atomic import atomic_write
    import tomllib

    from fabkit.materials import library, load_material, parse_material

    if args.calibrate:
        from fabkit.materials.calibrate import load_calibration

        if not args.output:
            raise InputError("--calibrate needs -o OUT.toml", source="--output")
        if Path(args.output).resolve() == Path(args.calibrate).resolve():
            raise InputError("the output would overwrite the calibration file", source=args.output)
        if not Path(args.output).parent.is_dir():
            raise InputError("output directory does not exist", source=args.output)
        cal = load_calibration(args.calibrate)
        text = cal.toml(args.calibrate)
        parse_material(tomllib.loads(text), args.output)  # what we write reads back as a material
        with atomic_write(args.output) as fh:
            fh.write(text)
        write_report(args, {"command": "materials", "ok": True, "calibration": cal.summary(), "output": args.output})
        say(args, f"{args.output}: {cal.material.name}, springback factor {cal.factor:.4g} from {len(cal.folds)} "
                  f"test fold(s) (rms residual {cal.summary()['rms_residual_deg']:.3g} deg)")
        return 0
    if args.output:
        raise InputError("-o is only used with --calibrate", source="--output")
    mats = {str(p): load_material(p) for p in args.files} if args.files else library()
    write_report(args, {"command": "materials", "ok": True, "materials": [m.summary() for m in mats.values()]})
    if not getattr(args, "quiet", False):
        from rich.console import Console
        from rich.table import Table

        table = Table(title="sheet materials (typical values, not for design)")
        for col in ("name", "yield MPa", "UTS MPa", "E GPa", "kg/m^3", "springback factor", "K-factor",
                    "min R_i at 1 mm", "creases"):
            table.add_column(col)
        for m in mats.values():
            table.add_row(*_row(m))
        Console(file=sys.stdout, width=140).print(table)
    return 0
