"""`python -m bench.cup_pretest_agreement [N]`: the cup pre-test against the full cup rule on every
set-up of the production bench's first N panels (default 40, every panel with N=0).

Per set-up (`fabkit.panels.production_refold.panel_setups`): the refold-free verdict
(`refusal_before_refold` with `sim.production.cup_refusal_before_refold`) and, when the set-up
refolds, the full rule on its FOLD file (`sim.production.cup_refusal`, the check's own rule).
A pre-test refusal where the full rule accepts is unsound; a full refusal the pre-test lets
through is a missed saving. Prints the counts and every disagreement; exits 1 on an unsound one
or on a refusal text that differs.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from bench.bench_production import CELL


def main(argv=None) -> int:
    from fabkit.generate.pleated import pleated_vault
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.production import ProductionOptions, program_task, stock
    from fabkit.panels.production_refold import _refold_solver, _solve, panel_setups, refusal_before_refold
    from fabkit.panels.surface import GridSurface, grid_from_topology
    from fabkit.panels.workflow import PanelsOptions, run_panels
    from sim.production import _cell, cup_refusal, cup_refusal_before_refold, program_panel

    argv = sys.argv[1:] if argv is None else argv
    n = int(argv[0]) if argv else 40
    mesh = pleated_vault(rows=30, columns=96)
    index, _ = grid_from_topology(mesh)
    layout = layout_panels(GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), cols=16,
                           columns_per_panel=6)
    panels = layout.panels[:n] if n else layout.panels
    geo = run_panels(layout, PanelsOptions())
    text = CELL.read_text()
    cell = _cell(text, CELL.name)
    counts = {"set-ups": 0, "pre-test refuses": 0, "full refuses": 0, "refold fails": 0, "unsound": 0,
              "missed": 0, "text differs": 0}
    t_pre = t_full = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for p in panels:
            task = program_task(p, geo.results[p.id], ProductionOptions(), text, CELL.name, stock(), program_panel,
                                cup_refusal_before_refold)
            for setup in panel_setups(task):
                counts["set-ups"] += 1
                prepared = _refold_solver(task, setup)
                if isinstance(prepared, str):
                    counts["refold fails"] += 1
                    continue
                t0 = time.perf_counter()
                pre = refusal_before_refold(task, setup, prepared[0])
                t_pre += time.perf_counter() - t0
                counts["pre-test refuses"] += bool(pre)
                _, fold, why = _solve(task, *prepared)
                if fold is None:
                    counts["refold fails"] += 1
                    print(f"{p.name} {setup.describe()}: refold fails ({why[:80]}); pre-test: {bool(pre)}")
                    continue
                path = Path(tmp) / f"{p.name}.fold"
                path.write_text(fold)
                t0 = time.perf_counter()
                full = cup_refusal(path, cell, setup.grip)
                t_full += time.perf_counter() - t0
                counts["full refuses"] += bool(full)
                if pre and not full:
                    counts["unsound"] += 1
                    print(f"UNSOUND {p.name} {setup.describe()}: {pre}")
                elif full and not pre:
                    counts["missed"] += 1
                    print(f"missed {p.name} {setup.describe()}: {full}")
                elif pre and f"holds: {full} (" not in pre:
                    counts["text differs"] += 1
                    print(f"text {p.name} {setup.describe()}:\n  full: {full}\n  pre:  {pre}")
    print(counts, f"pre-test {t_pre:.2f} s, full rule on the FOLD {t_full:.2f} s (refolds not counted)")
    return 1 if counts["unsound"] or counts["text differs"] else 0


if __name__ == "__main__":
    sys.exit(main())
