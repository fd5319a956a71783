"""The send interlock's cost: `robot.interlock.clear_for_send` (hashes, limits and the check run
again) on a planned fold program, against `sim.check.check_toolpath` of the same program in the
same run (the ratio is the interlock's overhead over one check).

The program: a 3 x 5 grid (strip 2 folded up 60 deg, 9 states) and a 6 x 32 grid (192 faces, the
size of the demo panel, 10 deg per crease), each planned into the ur5e_bench cell with its FOLD file
named in the toolpath. The first call in the process includes MuJoCo's start-up (reported apart).
"""
from __future__ import annotations

import json
import math
import sys
import tempfile
import time
from pathlib import Path

from bench.common import best_time, report

ROOT = Path(__file__).resolve().parent.parent


def _job(d: Path, fine: bool):
    sys.path.insert(0, str(ROOT / "tests"))
    from fold_fixtures import folded_grid_model

    from fabkit.frames import middle_row_frames
    from fabkit.io.fold import save_fold
    from robot.cell import file_sha256, load_cell
    from robot.toolpath import plan_panel

    cell = load_cell(ROOT / "cells" / "ur5e_bench.toml")
    if fine:
        model = folded_grid_model(n_strips=6, n_columns=32, strip_width=0.1, length=0.5, n_states=9,
                                  angles=[math.radians(10)] * 5, clamp_strip=0)
    else:
        model = folded_grid_model(n_states=9, angles=[0.0, math.radians(60)], clamp_strip=0, triangulate=True)
    fold = d / ("fine.fold" if fine else "grid.fold")
    save_fold(model, fold)
    source = {"file": fold.name, "sha256": file_sha256(fold)}
    tp = plan_panel(cell, middle_row_frames(model), source=source).toolpath
    tp.save(d / "path.json")
    return cell, tp, fold


def main() -> dict:
    from robot.interlock import clear_for_send
    from sim.check import check_toolpath

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for fine in (False, True):
            d = Path(tmp) / ("fine" if fine else "grid")
            d.mkdir()
            cell, tp, fold = _job(d, fine)
            t0 = time.perf_counter()
            report_ = check_toolpath(tp, cell, fold=fold)
            first = time.perf_counter() - t0
            assert report_.ok, [p.detail for p in report_.problems]
            check = json.loads(json.dumps(report_.to_json()))
            t_check = best_time(lambda: check_toolpath(tp, cell, fold=fold), repeat=5)
            t_gate = best_time(lambda: clear_for_send(tp, check, cell, fold=fold), repeat=5)
            rows.append({"program": f"{'6x32' if fine else '3x5'} grid", "waypoints": len(tp),
                         "panel_faces": report_.panel_faces, "configs": report_.configs_checked,
                         "first_check_s": first, "check_s": t_check, "interlock_s": t_gate,
                         "interlock/check": t_gate / t_check})
    return report("interlock", rows, {"note": "best of 5; first_check_s includes MuJoCo start-up"})


if __name__ == "__main__":
    main()
