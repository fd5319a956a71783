"""Sheet options shared by the commands that need a material (--material, --thickness, --crease,
--ligament, --bend-radius); the models are in `fabkit.sheet`."""
from __future__ import annotations


def add_sheet_arguments(parser, tool_mass: bool = False, material_help: str | None = None) -> None:
    g = parser.add_argument_group("sheet (docs/sheet.md)")
    g.add_argument("--material", metavar="M", default=None if material_help else "none",
                   help=material_help or "sheet material: a name from `fabkit materials` or a material .toml file "
                                         "(default none: rigid, no springback, no payload)")
    g.add_argument("--thickness", metavar="T", help="sheet thickness with its unit, e.g. 1mm, 1.6 mm, 0.002m")
    g.add_argument("--crease", choices=("plain", "grooved", "perforated"), default="plain",
                   help="crease preparation (default plain)")
    g.add_argument("--ligament", metavar="T", help="grooved creases: ligament left under the groove (default: the "
                                                    "material's), with its unit")
    g.add_argument("--bend-radius", metavar="R", help="inside bend radius of the creases with its unit (default: the "
                                                       "material's minimum for the crease preparation)")
    if tool_mass:
        g.add_argument("--tool-mass", type=float, default=None, metavar="KG",
                       help="gripper mass for the payload [kg] (default 1.0, an estimate: give the real one)")


def sheet_from_args(args):
    """The `SheetSpec` the options name (InputError naming the option on bad values)."""
    from fabkit.sheet import sheet_of

    return sheet_of("none" if args.material is None else args.material, args.thickness, args.crease,
                    ligament=args.ligament, bend_radius=args.bend_radius)
