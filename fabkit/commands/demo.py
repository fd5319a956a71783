"""`fabkit demo`: the whole pipeline on the built-in tri-fold panel, one stage after another.

Each stage is one call of the Python API (`fabkit.pipeline`, in `fabkit.commands._demo_stages`)
plus the files its subcommand writes; the summary table and the HTML page are read from the typed
results. A stage whose input an earlier failed stage should have made is listed as skipped.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from fabkit.commands._common import write_json

HELP = """Run the whole pipeline on the built-in tri-fold panel (paper Fig. 3) into DIR:
generate -> relax -> unfold (DXF/SVG) -> refold (FOLD animation) -> toolpath (UR5e bench cell)
-> MuJoCo check (PNG/MP4) -> dry run on the controller stand-in -> report.html.

Every stage runs through the Python API (`import fabkit.pipeline as fk`, docs/api.md). Prints a
summary table (measure, tolerance, pass/fail, time per stage) and exits 1 if any stage misses its
tolerance.

--material and --thickness plan and check the program for that sheet, as `fabkit toolpath
--material` and `fabkit check` do: springback-compensated fold states, the payload, the fold
loads (a load over the arm's or the cup's rating fails the check stage), the panel's thickness.

example:
  fabkit demo --out demo-out
  fabkit demo --out demo-out --material 5052-H32 --thickness 1mm
"""

REPO = Path(__file__).resolve().parents[2]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="demo-out", metavar="DIR", help="output folder (default: demo-out)")
    p.add_argument("--cell", default=str(REPO / "cells" / "ur5e_bench.toml"), help="robot cell (TOML)")
    p.add_argument("--frames", type=int, default=None,
                   help="fold states in the refold sequence (default 12; 4 with --small)")
    p.add_argument("--small", action="store_true", help="a smaller panel and fewer frames (for tests)")
    p.add_argument("--no-render", action="store_true", help="skip the PNG/MP4 renders of the check")
    p.add_argument("--no-dry-run", action="store_true", help="skip the controller stand-in dry run")
    p.add_argument("--material", metavar="M", default="none",
                   help="sheet material: a name from `fabkit materials` or a material .toml file (default none)")
    p.add_argument("--thickness", metavar="T",
                   help="sheet thickness with its unit, e.g. 1mm (needed with --material; without: a 1 mm slab)")
    p.add_argument("--report", metavar="R.json", help="write the summary as JSON")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary table")


def plan_files(args, plan) -> None:
    plan.input(args.cell, "--cell")
    plan.workdir(args.out, "--out")
    plan.output(Path(args.out) / "summary.json", "--out")
    plan.output(Path(args.out) / "report.html", "--out")
    plan.output(args.report, "--report")


@dataclass
class Stage:
    name: str
    status: str = "pending"  # pass | fail | skipped | error
    exit_code: int | None = None
    seconds: float = 0.0
    report: dict = field(default_factory=dict)
    message: str = ""
    measure: str = ""
    tolerance: str = ""


def _run_stage(stage: Stage, step, run, done: dict, reports: Path) -> None:
    """One stage through the API: its verdicts set the status (refused input: error, exit code 2)."""
    from fabkit.errors import InputError

    t0 = time.perf_counter()
    try:
        outcome = step(run, done)
    except InputError as exc:
        stage.status, stage.exit_code, stage.message = "error", 2, f"fabkit {stage.name}: {exc}"
        return
    finally:
        stage.seconds = time.perf_counter() - t0
    result = outcome.result
    done[stage.name] = result
    refusal = getattr(result, "refusal_line", None)  # a program the planner's check refused
    stage.status, stage.exit_code = ("pass", 0) if result.ok and refusal is None else ("fail", 1)
    stage.message = "; ".join((*result.problems, *([refusal] if refusal else [])))
    stage.report, stage.measure, stage.tolerance = outcome.report, outcome.measure, outcome.tolerance
    write_json(reports / f"{stage.name}.json", outcome.report)


def sheet_thickness(args) -> float | None:
    """The check's sheet thickness [m] from --material / --thickness (None: the check's default)."""
    from fabkit.errors import InputError
    from fabkit.materials import get_material, parse_length
    from fabkit.sheet import sheet_spec

    material = get_material(args.material)
    t = None if args.thickness is None else parse_length(args.thickness, "--thickness")
    if material.rigid:
        if t is not None:
            raise InputError("--thickness needs a --material other than none", source="--material")
        return None
    return sheet_spec(material, t).thickness


def run(args) -> int:
    from fabkit.commands._demo_stages import STAGES, DemoRun
    from fabkit.errors import InputError
    from fabkit.verdicts import MAX_REFOLD_FRAMES
    from robot.cell import load_cell

    frames = args.frames if args.frames is not None else 4 if args.small else 12
    if not 2 <= frames <= MAX_REFOLD_FRAMES:
        raise InputError(f"must be in 2..{MAX_REFOLD_FRAMES} (flat and target included), got {frames}",
                         source="--frames")
    thickness = sheet_thickness(args)
    load_cell(args.cell)  # a broken cell is refused before the first stage
    renders = () if args.no_render else ("check.png", "check.mp4")
    if renders:
        from sim.render import select_gl_backend  # before anything imports mujoco

        if select_gl_backend() is None:
            raise InputError("no offscreen OpenGL backend (install libegl1 libegl-mesa0 libgl1-mesa-dri, or "
                             "libosmesa6; or pass --no-render)", source="--render")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    reports = out / "reports"
    reports.mkdir(exist_ok=True)
    run_ = DemoRun(out=out, cell=args.cell, frames=frames, preset_params={"resolution": 6} if args.small else {},
                   renders=renders, thickness=thickness, material=args.material)
    names = [n for n in STAGES if not (n == "send" and args.no_dry_run)]
    stages = [Stage(n) for n in names]
    done: dict = {}
    t_all = time.perf_counter()
    failed_upstream = False
    for st in stages:
        if failed_upstream:  # every later stage needs this stage's result
            st.status, st.message = "skipped", "needs an earlier stage"
            continue
        _run_stage(st, STAGES[st.name], run_, done, reports)
        failed_upstream = st.status != "pass"
    total = time.perf_counter() - t_all
    summary = {
        "format": "fabkit.demo/1",
        "out": str(out),
        "total_seconds": total,
        "stages": [{"name": s.name, "status": s.status, "exit_code": s.exit_code, "seconds": s.seconds,
                    "measure": s.measure, "tolerance": s.tolerance, "message": s.message, "report": s.report}
                   for s in stages],
    }
    write_json(out / "summary.json", summary)
    if args.report:
        write_json(args.report, summary)
    from fabkit.report.html import write_report_html

    write_report_html(out, summary)
    if not args.quiet:
        _print_table(stages, total, out)
    return 1 if any(s.status in ("fail", "error") for s in stages) else 0


def _print_table(stages: list[Stage], total: float, out: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    colour = {"pass": "green", "fail": "red", "error": "red", "skipped": "yellow"}
    table = Table(title=f"fabkit demo -> {out}  ({total:.1f} s)")
    for col in ("stage", "result", "measure", "tolerance", "time", "note"):
        table.add_column(col)
    for s in stages:
        table.add_row(s.name, f"[{colour.get(s.status, 'white')}]{s.status}[/]", s.measure, s.tolerance,
                      f"{s.seconds:.2f} s" if s.seconds else "", s.message)
    Console(file=sys.stdout, width=max(100, shutil.get_terminal_size((120, 20)).columns)).print(table)
    if (out / "report.html").exists():
        print(f"report: {os.path.abspath(out / 'report.html')}")
