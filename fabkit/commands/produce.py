"""The production part of `fabkit panels --cell`: program and check every panel, nest, book."""
from __future__ import annotations

import sys
import time
from pathlib import Path

from fabkit.commands._common import say, write_json, write_report
from fabkit.errors import InputError


def _stage_printer(args):
    """Progress per stage on stderr: one line per stage at every tenth of its panels."""
    last: dict[str, int] = {}

    def show(stage: str, done: int, total: int | None) -> None:
        if args.quiet:
            return
        if total is None:
            if done % 50 == 0:
                print(f"  {stage}: {done} tasks", file=sys.stderr, flush=True)
            return
        step = max(1, total // 10)
        if done == total or done // step != last.get(stage, -1):
            last[stage] = done // step
            print(f"  {stage}: {done}/{total} panels", file=sys.stderr, flush=True)

    return show


def _parse_sheet(text: str) -> tuple[float, float]:
    try:
        w, h = (float(x) for x in text.lower().split("x"))
    except ValueError:
        raise InputError(f"expected WIDTHxHEIGHT in mm, e.g. 2500x1250, got {text!r}", source="--sheet") from None
    if not (w > 0 and h > 0):
        raise InputError(f"sheet sides must be positive, got {text!r}", source="--sheet")
    return w, h


def _overrides(path: str | None) -> dict:
    if not path:
        return {}
    from fabkit.io.jsonfile import load_json

    data = load_json(path, "overrides file")
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        raise InputError('expected {"PANEL_NAME": {"frames": N}, ...}', source=path)
    for name, opts in data.items():
        bad = set(opts) - {"frames"}
        if bad:
            raise InputError(f"panel {name}: unknown option(s) {', '.join(sorted(bad))} (known: frames)", source=path)
        if not isinstance(opts.get("frames", 2), int) or opts.get("frames", 2) < 2:
            raise InputError(f"panel {name}: frames must be an integer >= 2", source=path)
    return data


def _sheet_and_stock(args):
    """(the `SheetSpec` the programs follow, or None for the design angles; the `Stock` the sheets
    are cut from) of the sheet options."""
    from fabkit.commands._sheet import sheet_from_args
    from fabkit.panels.production import stock

    if args.tool_mass is not None and not 0 <= args.tool_mass <= 20:
        raise InputError(f"{args.tool_mass} kg is not in [0, 20]", source="--tool-mass")
    if args.material is None and args.thickness is None and args.crease == "plain" and args.ligament is None \
            and args.bend_radius is None:
        return None, stock()
    if args.material is None:
        raise InputError("--thickness, --crease, --ligament and --bend-radius need a --material", source="--material")
    spec = sheet_from_args(args)
    if spec.rigid:
        raise InputError("a production run cuts real sheet: name a material (`fabkit materials` lists them)",
                         source="--material")
    return spec, stock(args.material, spec.thickness)


def run_production_command(args, surface, lowpoly: bool, layout) -> int:
    from fabkit.nest import NestOptions, nest_panels, write_sheets
    from fabkit.panels.output import write_run
    from fabkit.panels.production import ProductionOptions, run_production, stock
    from fabkit.panels.repeats import SAME_PART_TOL
    from fabkit.panels.production_report import summary
    from fabkit.panels.workflow import PanelsOptions
    from fabkit.report.book import write_book
    from sim.production import carry_over, cup_refusal_before_refold, program_panel

    cell_path = Path(args.cell)
    if not cell_path.is_file():
        raise InputError("cell file not found", source=args.cell)
    from robot.cell import load_cell

    load_cell(cell_path)  # refuse a bad cell before any work
    spec, mat = _sheet_and_stock(args)
    sheet = _parse_sheet(args.sheet)
    if args.frames < 2:
        raise InputError(f"must be >= 2 (flat and folded), got {args.frames}", source="--frames")
    from fabkit.nest.spacing import cut_spacing

    cut = cut_spacing(mat.thickness * 1e3, args.cut, spacing=args.spacing, kerf=args.kerf, edge=args.edge_margin)
    overrides = _overrides(args.overrides)
    unknown = sorted(set(overrides) - {p.name for p in layout.panels})
    if unknown:
        raise InputError(f"no panel named {unknown[0]}", source=args.overrides)
    popts = PanelsOptions(tol_congruency=args.tolerance, tol_unfold=args.unfold_tolerance,
                          max_rounds=args.max_rounds, symmetric=args.symmetric,
                          keep_shared_edges=not args.free_shared_edges)
    out = Path(args.out)
    t0 = time.perf_counter()
    show = _stage_printer(args)
    from fabkit.panels.executor import panel_executor

    with panel_executor(args.jobs, args.scheduler) as ex:  # one pool of workers for every stage
        run = run_production(layout, out, cell_toml=cell_path.read_bytes().decode("utf-8"), cell_name=cell_path.name,
                             program=program_panel, panels_options=popts, carry=carry_over,
                             options=ProductionOptions(frames=args.frames, overrides=overrides,
                                                       same_part_tol=None if args.each_panel else SAME_PART_TOL,
                                                       sheet=spec, tool_mass=args.tool_mass),
                             mat=mat, jobs=args.jobs, scheduler=args.scheduler, progress=show, executor=ex,
                             refuse_before_refold=cup_refusal_before_refold)
        t1 = time.perf_counter()
        write_run(run.geometry, out, plots=not args.no_plots, cut_files=True, executor=ex)
    seconds = dict(run.seconds)
    seconds["geometry_files"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    nopts = NestOptions.for_cut(cut, sheet=sheet, grain=args.grain, engine=args.nester, time_limit=args.nest_seconds)
    nesting = nest_panels(run, nopts)
    show("nesting", len(nesting.placements), len(layout.panels))
    sheets = write_sheets(run, nesting, out / "sheets", mat, sheet=spec)
    seconds["nesting"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    report = summary(run, nesting, mat, layout)
    report["input"] = {"surface": args.surface, "lowpoly": lowpoly, "cell": str(cell_path)}
    report["sheets"] = sheets
    report["programs_sheet"] = None if spec is None else spec.summary()  # None: the design angles, no loads
    write_book(run, nesting, report, out)
    seconds["book"] = time.perf_counter() - t1
    seconds["total"] = time.perf_counter() - t0
    report["seconds"] = seconds
    write_json(out / "production.json", report)
    write_report(args, report)
    tot = report["totals"]
    say(args, f"{tot['panels']} panels: {tot['ok']} ok, {tot['failed']} failed; robot time {tot['robot_time_s'] / 60:.1f} min; "
              f"{tot['sheets']} sheets {sheet[0]:g}x{sheet[1]:g} mm ({tot['utilisation']:.1%} used), "
              f"{tot['material_kg']:.1f} kg {mat.name}; recomputed {len(run.recomputed['relax_unfold'])} relax, "
              f"{len(run.recomputed['refold_program_check'])} programs ({len(run.same_as)} of them as the same "
              f"part as another panel) -> {out}/book.html")
    for p in [p for p in run.panels if not p.ok][:5]:
        say(args, f"  {p.name}: {p.stage}: {p.reason}")
    return 0 if run.ok else 1
