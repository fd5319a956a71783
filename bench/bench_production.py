"""Production run at scale: the 494-panel pleated vault end to end on 2 workers.

Stages: geometry (layout, relax, unfold, congruency), refold + program + check of every panel
(once per part: panels that are the same part to 0.1 um share them, `fabkit.panels.repeats`),
geometry files, nesting, sheets and book. Target: <= 120 s in all.

Nesting utilisation = total panel (flat pattern) area / area of the sheets used, every sheet counted
whole (the strict number; target >= 75 %), and also with the last sheet counted only up to its
used length (the rest an offcut). Engines in the same run: the bounding-box shelf packing
(baseline), row nesting (`rows`, the default) and sparrow (`packingsolver`, 10 s per strip solve),
all at the distances `fabkit panels --cell` gives the run's 1 mm 5052-H32 sheet, laser cut
(`fabkit.nest.spacing.cut_spacing`: 2.2 mm between parts, 5 mm to the edge; `python -m bench
nesting` compares them with the 10 mm spacing used before).

On a shared machine the wall time is inflated by the other processes; the CPU seconds of the main
process and of the workers are printed too, and main CPU + workers' CPU / 2 as the estimate of the
wall time on two otherwise idle cores (stated as an estimate).

FABKIT_BENCH_PROGRAMS=N refolds, programs and checks only the first N panels (`select`; the rest
end "not selected"), to measure the other stages on a shared machine; the per-panel cost and the
extrapolated total are printed so the full run can be judged. Default: every panel.
FABKIT_BENCH_MANIFEST=FILE copies the run's manifest.json (every panel's stage, reason and set-ups)
there, to compare the verdicts of two runs (`bench/compare_verdicts.py`).
"""
from __future__ import annotations

import os
import resource
import tempfile
import time
from pathlib import Path

from bench.common import report

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / "cells" / "ur5e_bench_40mm_cup.toml"  # the vault's strips are too narrow for the 50 mm cup


def main() -> dict:
    from fabkit.generate.pleated import pleated_vault
    from fabkit.nest import NestOptions, nest_panels, write_sheets
    from fabkit.nest.spacing import cut_spacing
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.executor import panel_executor
    from fabkit.panels.output import write_run
    from fabkit.panels.production import run_production, stock
    from fabkit.panels.production_report import summary
    from fabkit.panels.surface import GridSurface, grid_from_topology
    from fabkit.report.book import write_book
    from sim.production import carry_over, cup_refusal_before_refold, program_panel
    rows = []
    jobs = 2
    load0 = os.getloadavg()[0]
    t_all = time.perf_counter()
    t0 = time.perf_counter()
    mesh = pleated_vault(rows=30, columns=96)
    index, _ = grid_from_topology(mesh)
    layout = layout_panels(GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), cols=16,
                           columns_per_panel=6)
    t_layout = time.perf_counter() - t0
    n_prog = int(os.environ.get("FABKIT_BENCH_PROGRAMS", len(layout.panels)))
    mat = stock("5052-H32", 1.0e-3)
    with tempfile.TemporaryDirectory(prefix="fabkit-bench-production-") as tmp:
        out = Path(tmp) / "run"
        subset = {p.name for p in layout.panels[:n_prog]}
        with panel_executor(jobs) as ex:  # one pool of workers for every stage, as `fabkit panels --cell`
            run = run_production(layout, out, cell_toml=CELL.read_bytes().decode("utf-8"), cell_name=CELL.name,
                                 program=program_panel, jobs=jobs, mat=mat, timeout=3600, select=subset,
                                 carry=carry_over, executor=ex, refuse_before_refold=cup_refusal_before_refold)
            t0 = time.perf_counter()
            write_run(run.geometry, out, plots=False, cut_files=True, executor=ex)
            t_files = time.perf_counter() - t0
        t0 = time.perf_counter()
        cut = cut_spacing(mat.thickness * 1e3, "laser")  # as `fabkit panels --cell` for this sheet
        nest = nest_panels(run, NestOptions.for_cut(cut, engine="rows"))
        t_nest = time.perf_counter() - t0
        sheets = write_sheets(run, nest, out / "sheets", mat)
        rep = summary(run, nest, mat, layout)
        rep["input"] = {"surface": "pleated_vault(rows=30, columns=96)", "cell": CELL.name}
        rep["sheets"] = sheets
        write_book(run, nest, rep, out)
        t_book = time.perf_counter() - t0 - t_nest
        total = time.perf_counter() - t_all
        own = resource.getrusage(resource.RUSAGE_SELF)
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)  # the pools' workers, reaped at their shutdown
        cpu_self, cpu_workers = own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime
        programmed = [p for p in run.panels if p.name in subset]
        computed = len({p.name for p in programmed} - set(run.same_as))
        per_panel = run.seconds["refold_program_check"] / max(1, len(programmed))
        with_files = sum(1 for p in run.panels if {"refold", "program", "check"} <= set(p.files) or p.stage)
        import json

        entries = json.loads((out / "manifest.json").read_text())["panels"]
        if os.environ.get("FABKIT_BENCH_MANIFEST"):
            Path(os.environ["FABKIT_BENCH_MANIFEST"]).write_text((out / "manifest.json").read_text())
        computed_entries = [e for e in entries.values() if e.get("setups") and not e.get("same_as")]
        tried = sum(sum(s["stage"] != "skipped" for s in e["setups"]) for e in computed_entries)
        refolded = sum(sum(s["stage"] != "skipped" and "run before the refold" not in s["reason"] for s in e["setups"])
                       for e in computed_entries)
        rows.append({"case": f"{len(layout.panels)} panels, {len(programmed)} programmed + checked "
                             f"({computed} computed, {len(run.same_as)} as the same part)", "workers": jobs,
                     "seconds": total, "layout s": t_layout, "relax+unfold s": run.seconds["relax_unfold"],
                     "same-part grouping s": run.seconds.get("same_parts", 0.0),
                     "refold+program+check s": run.seconds["refold_program_check"],
                     "all panels extrapolated s": total + per_panel * (len(layout.panels) - len(programmed)),
                     "geometry files s": t_files, "nesting (rows) s": t_nest, "sheets+book s": t_book,
                     "target s": 120.0, "load average at start": load0, "load average at end": os.getloadavg()[0],
                     "cpu s (main process)": cpu_self, "cpu s (workers)": cpu_workers,
                     "2 idle cores estimate s (main cpu + workers cpu / 2)": cpu_self + cpu_workers / 2,
                     "ok": sum(p.ok for p in run.panels), "with files or a named reason": with_files,
                     "failed by stage": {k: v for k, v in rep["totals"]["failed_by_stage"].items()},
                     "robot time min": run.robot_time_s / 60,
                     "set-ups tried (computed parts)": tried, "set-ups refolded (computed parts)": refolded,
                     "seconds per computed part (workers)": cpu_workers / max(1, computed)})
        nests = {"rows": nest}
        for engine, limit in (("shelf", 0), ("packingsolver", 10)):
            nests[engine] = nest_panels(run, NestOptions.for_cut(cut, engine=engine, time_limit=limit))
        for engine, n in nests.items():
            nn = n.nesting
            problems = nn.verify(n.parts)
            rows.append({"case": f"nesting {engine}", "sheets": nn.n_sheets, "seconds": nn.seconds,
                         "utilisation (whole sheets)": nn.utilisation,
                         "utilisation (last sheet by length)": nn.used_length_utilisation(n.parts),
                         "ratio to shelf (whole sheets)": nn.utilisation / nests["shelf"].nesting.utilisation,
                         "verified (each once, inside, gap)": not problems, "target": 0.75})
    return report("production", rows, {"panels": len(layout.panels), "programmed": n_prog,
                                       "sheet mm": [2500, 1250], "gap mm": 10.2})


if __name__ == "__main__":
    main()
