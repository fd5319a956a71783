"""Production run at scale: the 494-panel pleated vault end to end on 2 workers.

Stages: geometry (layout, relax, unfold, congruency), refold + program + check of every panel,
geometry files, nesting, sheets and book. Target: <= 120 s in all. Baseline in the same run: the
bounding-box shelf packing, against which sparrow's nesting utilisation is compared (target
>= 75 %).

FABKIT_BENCH_PROGRAMS=N refolds, programs and checks only the first N panels (`select`; the rest
end "not selected"), to measure the other stages on a shared machine; the per-panel cost and the
extrapolated total are printed so the full run can be judged. Default: every panel.
"""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from bench.common import report

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / "cells" / "ur5e_bench.toml"


def main() -> dict:
    from fabkit.generate.pleated import pleated_vault
    from fabkit.nest import NestOptions, nest_panels, write_sheets
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.output import write_run
    from fabkit.panels.production import run_production, stock
    from fabkit.panels.production_report import summary
    from fabkit.panels.surface import GridSurface, grid_from_topology
    from fabkit.report.book import write_book
    from sim.production import program_panel
    rows = []
    jobs = 2
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
        run = run_production(layout, out, cell_toml=CELL.read_text(), cell_name=CELL.name, program=program_panel,
                             jobs=jobs, mat=mat, timeout=3600, select=subset)
        t0 = time.perf_counter()
        write_run(run.geometry, out, plots=False, cut_files=True)
        t_files = time.perf_counter() - t0
        nests = {}
        for engine, limit in (("shelf", 0), ("packingsolver", 20)):
            nests[engine] = nest_panels(run, NestOptions(engine=engine, time_limit=limit))
        t0 = time.perf_counter()
        sheets = write_sheets(run, nests["packingsolver"], out / "sheets", mat)
        rep = summary(run, nests["packingsolver"], mat, layout)
        rep["input"] = {"surface": "pleated_vault(rows=30, columns=96)", "cell": CELL.name}
        rep["sheets"] = sheets
        write_book(run, nests["packingsolver"], rep, out)
        t_book = time.perf_counter() - t0
        total = time.perf_counter() - t_all
        programmed = [p for p in run.panels if p.name in subset]
        per_panel = run.seconds["refold_program_check"] / max(1, len(programmed))
        sh, sp = nests["shelf"].nesting, nests["packingsolver"].nesting
        rows.append({"case": f"{len(layout.panels)} panels, {len(programmed)} programmed + checked", "workers": jobs,
                     "seconds": total, "layout s": t_layout, "relax+unfold s": run.seconds["relax_unfold"],
                     "refold+program+check s": run.seconds["refold_program_check"],
                     "s per programmed panel (2 workers)": per_panel,
                     "all panels extrapolated s": total + per_panel * (len(layout.panels) - len(programmed)),
                     "geometry files s": t_files, "sheets+book s": t_book, "target s": 120.0,
                     "ok": sum(p.ok for p in run.panels),
                     "failed by stage": {k: v for k, v in rep["totals"]["failed_by_stage"].items()},
                     "robot time min": run.robot_time_s / 60})
        for engine, nest in nests.items():
            n = nest.nesting
            rows.append({"case": f"nesting {engine}", "sheets": n.n_sheets, "seconds": n.seconds,
                         "utilisation (whole sheets)": n.utilisation,
                         "utilisation (last sheet by length)": n.used_length_utilisation(nest.parts),
                         "target": 0.75})
        rows[-1]["ratio to shelf (whole sheets)"] = sp.utilisation / sh.utilisation
        rows[-1]["ratio to shelf (last sheet by length)"] = (sp.used_length_utilisation(nests["packingsolver"].parts)
                                                             / sh.used_length_utilisation(nests["shelf"].parts))
    return report("production", rows, {"panels": len(layout.panels), "programmed": n_prog,
                                       "spline/relief": "see sheets"})


if __name__ == "__main__":
    main()
