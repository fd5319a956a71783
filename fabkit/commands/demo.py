"""`fabkit demo`: the whole pipeline on the built-in tri-fold panel, one stage after another.

Each stage runs through its own subcommand (the same code path a user's shell command takes)
with a JSON report; the demo reads the reports back for the summary table and the HTML page.
A stage whose input an earlier failed stage should have made is listed as skipped.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from fabkit.commands._common import say, write_json

HELP = """Run the whole pipeline on the built-in tri-fold panel (paper Fig. 3) into DIR:
generate -> relax -> unfold (DXF/SVG) -> refold (FOLD animation) -> toolpath (UR5e bench cell)
-> MuJoCo check (PNG/MP4) -> dry run on the controller stand-in -> report.html.

Prints a summary table (measure, tolerance, pass/fail, time per stage) and exits 1 if any stage
misses its tolerance.

example:
  fabkit demo --out demo-out
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
    argv: list[str]
    status: str = "pending"  # pass | fail | skipped | error
    exit_code: int | None = None
    seconds: float = 0.0
    report: dict = field(default_factory=dict)
    message: str = ""
    measure: str = ""
    tolerance: str = ""


def _run_stage(stage: Stage, report_path: Path) -> None:
    """Run one subcommand in-process, capturing its stderr line(s) for the summary."""
    from fabkit.cli import main as cli_main

    err = io.StringIO()
    out = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = cli_main(stage.argv + ["--report", str(report_path), "--quiet"])
        except SystemExit as exc:  # argparse usage errors
            code = int(exc.code or 0)
    stage.seconds = time.perf_counter() - t0
    stage.exit_code = code
    stage.message = err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else ""
    if report_path.exists():
        with contextlib.suppress(ValueError, OSError):
            stage.report = json.loads(report_path.read_text())
    stage.status = {0: "pass", 1: "fail"}.get(code, "error")


def _first(d: dict, *keys, default=None):
    """First present key among dotted paths in a report."""
    for k in keys:
        cur = d
        ok = True
        for part in k.split("."):
            if isinstance(cur, dict) and part in cur:
                cur = cur[part]
            else:
                ok = False
                break
        if ok and cur is not None:
            return cur
    return default


def _fmt(x) -> str:
    if isinstance(x, float):
        return f"{x:.3g}"
    return str(x)


def _describe(stage: Stage) -> None:
    """Fill the measure/tolerance columns from a stage's report (best effort, keys per stage)."""
    r = stage.report
    if not r:
        return
    if stage.name == "relax":
        d = _first(r, "final.max_abs_angle_defect_rad", "max_abs_angle_defect_rad", "result.max_defect")
        p = _first(r, "final.max_planarity", "max_planarity", "result.max_planarity")
        stage.measure = f"max|defect| {_fmt(d)} rad, max planarity {_fmt(p)}"
        stage.tolerance = f"{_fmt(_first(r, 'options.tol_defect', 'tol_defect', default='-'))} / " \
                          f"{_fmt(_first(r, 'options.tol_planarity', 'tol_planarity', default='-'))}"
    elif stage.name == "unfold":
        stage.measure = (f"mean {_fmt(_first(r, 'development.mean_relative_deviation', default='?'))}, "
                         f"max {_fmt(_first(r, 'development.max_relative_deviation', default='?'))} rel. length dev., "
                         f"{_first(r, 'development.flipped_faces', default='?')} flipped")
        stage.tolerance = f"max <= {_fmt(_first(r, 'max_error', default='-'))}"
    elif stage.name == "refold":
        stage.measure = (f"loop closure {_fmt(_first(r, 'summary.max_loop_residual_rad', default='?'))} rad, "
                         f"edge err {_fmt(_first(r, 'summary.max_edge_length_error_rel', default='?'))}, "
                         f"target {_fmt(_first(r, 'summary.target_distance_rel', default='?'))} of size")
        stage.tolerance = f"target <= {_fmt(_first(r, 'target_tol', default='-'))}"
    elif stage.name == "toolpath":
        stage.measure = (f"{_first(r, 'waypoints', 'n_waypoints', default='?')} waypoints, "
                         f"max fold step {_fmt(_first(r, 'max_fold_joint_step_deg', default='?'))} deg, "
                         f"cycle {_fmt(_first(r, 'cycle_time_s', default='?'))} s")
        stage.tolerance = "step <= 5 deg"
    elif stage.name == "check":
        clearance = _first(r, "min_clearance_m")
        if clearance is None:  # nothing came within the checker's clearance window
            clearance_text = f"> {_fmt(_first(r, 'clearance_window_m', default='?'))} m"
        else:
            clearance_text = f"{_fmt(clearance)} m"
        stage.measure = (f"{_first(r, 'problems', default='?')} problems in {_first(r, 'configs_checked', default='?')} "
                         f"configurations, min clearance {clearance_text}")
        stage.tolerance = "0 problems"
    elif stage.name == "send":
        stage.measure = (f"{_first(r, 'last_completed', default=-1) + 1}/{_first(r, 'total', default='?')} waypoints, "
                         f"final error {_fmt(_first(r, 'final_error_m', default='?'))} m / "
                         f"{_fmt(_first(r, 'final_error_rad', default='?'))} rad")
        stage.tolerance = "all waypoints, error <= 1e-4 rad"
    elif stage.name == "generate":
        stage.measure = f"{_first(r, 'vertices', 'summary.vertices', default='?')} vertices, " \
                        f"{_first(r, 'faces', 'summary.faces', default='?')} faces"


def run(args) -> int:
    from fabkit.commands.refold import MAX_FRAMES
    from fabkit.errors import InputError
    from robot.cell import load_cell

    frames = args.frames if args.frames is not None else 4 if args.small else 12
    if not 2 <= frames <= MAX_FRAMES:
        raise InputError(f"must be in 2..{MAX_FRAMES} (flat and target included), got {frames}", source="--frames")
    load_cell(args.cell)  # a broken cell is refused before the first stage
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    reports = out / "reports"
    reports.mkdir(exist_ok=True)
    gen_params = ["--resolution", "6"] if args.small else []
    p = lambda name: str(out / name)  # noqa: E731
    stages = [
        Stage("generate", ["generate", "trifold", "-o", p("trifold.obj"), *gen_params]),
        Stage("relax", ["relax", p("trifold.obj"), "-o", p("relaxed.obj")]),
        Stage("unfold", ["unfold", p("relaxed.obj"), "-o", p("flat.obj"), "--dxf", p("flat.dxf"),
                         "--svg", p("flat.svg"), "--png", p("unfold_error.png"), "--max-error", "1e-6"]),
        Stage("refold", ["refold", p("flat.obj"), p("relaxed.obj"), "-o", p("fold.fold"),
                         "--frames", str(frames), "--png", p("fold_angles.png")]),
        Stage("toolpath", ["toolpath", p("fold.fold"), "--cell", args.cell, "-o", p("path.json"),
                           "--script", p("program.script")]),
        Stage("check", ["check", p("path.json"), "--cell", args.cell, "-o", p("check.json"),
                        *([] if args.no_render else ["--render", p("check.png"), "--render", p("check.mp4")])]),
    ]
    t_all = time.perf_counter()
    failed_upstream = False
    for st in stages:
        if failed_upstream:
            st.status, st.message = "skipped", "needs an earlier stage"
            continue
        _run_stage(st, reports / f"{st.name}.json")
        _describe(st)
        if st.status in ("fail", "error", "skipped"):
            failed_upstream = True  # every later stage needs this stage's output
    if not args.no_dry_run:
        dry = Stage("send", ["send", p("path.json"), "--check", p("check.json"), "--cell", args.cell])
        if failed_upstream:
            dry.status, dry.message = "skipped", "needs an earlier stage"
        else:
            _dry_run(dry, reports / "send.json", args.cell)
            _describe(dry)
        stages.append(dry)
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


def _dry_run(stage: Stage, report_path: Path, cell: str) -> None:
    """Start the controller stand-in on a free loopback address, send, verify, shut it down."""
    from fabkit.commands._dryrun import run_dry

    run_dry(stage, report_path, _run_stage, cell)


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
