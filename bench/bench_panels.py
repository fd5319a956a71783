"""Multi-panel workflow at scale: ~500 panels end to end (relax, unfold, congruency, one merge round).

Target: <= 120 s on 2 cores. Baseline in the same run: the same job on 1 worker, giving
the speed-up from 1 to 2 workers. Also the ~100-panel preset with the full feedback loop, with the
shared boundary edges kept in the relaxation (default) and, as the baseline in the same run, without
(panels relaxed independently; the 2D merge then has to absorb their 3D disagreement).
"""
from __future__ import annotations

import time

from bench.common import report
from fabkit.panels.layout import layout_panels
from fabkit.panels.surface import canopy_lowpoly, subdivide_grid
from fabkit.panels.workflow import PanelsOptions, run_panels


def _job(layout, jobs: int, rounds: int) -> tuple[float, object]:
    t0 = time.perf_counter()
    run = run_panels(layout, PanelsOptions(max_rounds=rounds, tol_congruency=0.0), jobs=jobs)
    return time.perf_counter() - t0, run


def main() -> dict:
    rows = []
    t0 = time.perf_counter()
    big = layout_panels(subdivide_grid(canopy_lowpoly(stations=8), 6), rows=30, cols=16, columns_per_panel=6)
    t_layout = time.perf_counter() - t0
    times = {}
    for jobs in (1, 2):
        seconds, run = _job(big, jobs, rounds=1)
        times[jobs] = seconds
        rows.append({"case": f"{len(big.panels)} panels, 1 merge round", "workers": jobs, "seconds": seconds,
                     "relax+unfold s": run.seconds["relax_unfold"], "congruency+merge s": run.seconds["congruency_merge"],
                     "layout s": t_layout, "relax converged": sum(r.converged for r in run.results),
                     "max incongruency": run.rounds[-1]["max_incongruency"],
                     "speed-up vs 1 worker": times[1] / seconds, "target s": 120.0})
    preset = layout_panels(subdivide_grid(canopy_lowpoly(stations=8), 4), rows=14, cols=7, columns_per_panel=6)
    preset_rows = {}
    for keep in (False, True):
        t0 = time.perf_counter()
        run = run_panels(preset, PanelsOptions(keep_shared_edges=keep), jobs=2)
        row = {"case": f"{len(preset.panels)}-panel preset, full feedback, shared edges "
                       f"{'kept' if keep else 'free (baseline)'}", "workers": 2,
               "seconds": time.perf_counter() - t0, "relax+unfold s": run.seconds["relax_unfold"],
               "congruency+merge s": run.seconds["congruency_merge"],
               "relax converged": sum(r.converged for r in run.results),
               "round-0 max incongruency": run.rounds[0]["max_incongruency"],
               "max incongruency": run.rounds[-1]["max_incongruency"],
               "max unfold deviation": run.rounds[-1]["max_unfold_deviation"],
               "panels over unfold tol": sum(r.unfold_max > run.options.tol_unfold for r in run.results),
               "rounds": len(run.rounds) - 1}
        preset_rows[keep] = row
        rows.append(row)
    preset_rows[True]["time vs baseline"] = preset_rows[True]["seconds"] / preset_rows[False]["seconds"]
    return report("panels", rows, {"panels_big": len(big.panels), "panels_preset": len(preset.panels)})


if __name__ == "__main__":
    main()
