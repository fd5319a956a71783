"""Sheet options shared by the commands that need a material (--material, --thickness, --crease,
--ligament, --bend-radius) and the toolpath's sheet records; the models are in `fabkit.sheet`."""
from __future__ import annotations


def add_sheet_arguments(parser, tool_mass: bool = False) -> None:
    g = parser.add_argument_group("sheet (docs/sheet.md)")
    g.add_argument("--material", metavar="M", default="none",
                   help="sheet material: a name from `fabkit materials` or a material .toml file (default none: "
                        "rigid, no springback, no payload)")
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
    from fabkit.materials import get_material, parse_length
    from fabkit.sheet import sheet_spec

    material = get_material(args.material)
    t = None if args.thickness is None else parse_length(args.thickness, "--thickness")
    lig = None if args.ligament is None else parse_length(args.ligament, "--ligament")
    r = None if args.bend_radius is None else parse_length(args.bend_radius, "--bend-radius", allow_zero=True)
    if material.rigid and (t is not None or args.crease != "plain" or lig is not None or r is not None):
        from fabkit.errors import InputError

        raise InputError("--thickness, --crease, --ligament and --bend-radius need a --material other than none",
                         source="--material")
    return sheet_spec(material, t, args.crease, ligament=lig, inside_radius=r)


def toolpath_sheet_record(args, spec, design_model, compensated, cell, tp, grip_face):
    """PATH.json's `sheet` (design/programmed angles per state, fold-load verdicts) and `payload`
    records for a planned toolpath; prints one line per exceeded load (crease, check, states,
    remedy). -> (toolpath with the records, `robot.loads.LoadReport`)."""
    import sys
    from dataclasses import replace

    from fabkit.sheet import panel_mass
    from robot.loads import payload_record, toolpath_loads
    from robot.motion import toolpath_cycle_time
    from robot.ur_motion import PayloadError

    if args.tool_mass is None:
        print("fabkit toolpath: note: payload with an assumed 1.0 kg gripper (give --tool-mass)", file=sys.stderr)
    tool_mass = 1.0 if args.tool_mass is None else float(args.tool_mass)
    flat = design_model.mesh()
    pm = panel_mass(spec, flat.vertices, flat.triangulate()[0])
    payload = payload_record(cell, tp.waypoints, pm.mass, pm.cog, tool_mass)
    loads = toolpath_loads(spec, design_model, compensated.creases, grip_face, cell, tool_mass + pm.mass)
    tp = replace(tp, extra={**tp.extra, "sheet": {**compensated.summary(), "loads": loads.summary()},
                            "payload": payload})
    try:  # the declared payload lowers the joint acceleration bound (robot.ur_motion)
        tp = replace(tp, extra={**tp.extra, "cycle_time_s": toolpath_cycle_time(tp).total})
    except PayloadError as exc:  # the load check reports the payload; the check refuses the toolpath
        print(f"fabkit toolpath: warning: {exc}", file=sys.stderr)
    seen: dict = {}
    for v in loads.failures:  # one line per crease and check, with the states it applies to
        seen.setdefault((v.crease, v.check), []).append(v)
    for (crease, check), vs in seen.items():
        worst = max(vs, key=lambda v: v.demand)
        print(f"fabkit toolpath: {'FAILED' if args.check_loads else 'warning'}: load check: {crease}, states "
              f"{','.join(str(v.state) for v in vs)}: {check} {worst.demand:.1f} {worst.unit} of "
              f"{worst.capacity:.1f} {worst.unit}; remedy: {worst.remedy}", file=sys.stderr)
    return tp, loads
