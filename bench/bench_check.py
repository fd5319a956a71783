"""Toolpath check speed: configurations checked per second and a 2,000-waypoint program end to end.

Programs: 2,000-waypoint tool-down sweeps over the panel in both shipped cells, with a 15-face
folded grid panel in the model 8 cm under the tool (so the panel pieces are in the broad phase).
`loops` sets how far apart the waypoints are: 1 loop ~ 1 mm apart (no interpolation needed),
4 loops ~ 4 mm apart with more rotation per step (interpolated steps and continuous IK on the
linear moves). Two more rows put the tool 2.5 cm over a 192-face panel (the size of the reflect
demo panel), the worst case for MuJoCo's convex-mesh narrow phase (every face near the tool is a
distance query).

Measured:
- `configs_per_s`: collision (mj_kinematics + mj_collision, contact classification) + joint limits +
  singularity factors over the interpolated configurations, the path `check_program` uses
  (one Python loop over MuJoCo, numpy for limits/singularities over all configurations at once),
  with the cell model built beforehand (`build_s`, once per check);
- `baseline_per_s`: the straightforward per-configuration loop (mj_forward, then limits and
  singularity factors called per configuration); `speedup` = configs_per_s / baseline_per_s;
- `full_check_s`: `check_program` end to end (interpolation with IK, all checks, model build).
Targets: >= 20,000 configurations/s on one core; a 2,000-waypoint program in <= 1 s.

Panel case (`sim.panel_collision`, which runs once per program, not per arm configuration): the
folded 15-face and 192-face grid panels in each cell against the obstacles (MuJoCo explicit pairs)
and themselves (triangle pairs), every state and the motion between sampled every 5 mm of corner
travel; `panel_samples_per_s` fractional fold states checked per second.

Two-arm case (`sim.arm_contacts.arm_arm_contacts`, the arm-against-arm part of the two-arm check):
2,000 lockstep configurations of both UR10e of `dual_ur10e` near their homes, 10 mm clearance;
baseline: the same model collided with every pair MuJoCo makes (each arm's own parts, obstacles)
and the contacts read one by one.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import mujoco
import numpy as np

from bench.common import best_time, report

ROOT = Path(__file__).resolve().parent.parent


def _panel(cell, fine: bool = False):
    """A folded grid panel: 3 strips x 5 columns (15 faces), or 6 x 32 (192 faces, the size of the
    reflect demo panel) for the `fine` rows."""
    import sys

    sys.path.insert(0, str(ROOT / "tests"))
    from fold_fixtures import folded_grid_model

    from sim.panel import panel_from_fold

    if fine:
        model = folded_grid_model(n_strips=6, n_columns=32, strip_width=0.1, length=0.5, n_states=3,
                                  angles=[math.radians(10)] * 5, clamp_strip=0)
    else:
        model = folded_grid_model(n_states=3, angles=[math.radians(30)] * 2, clamp_strip=0)
    return panel_from_fold(model, cell.fixture, grip_face_id=None)


def _baseline(cell, panel, Q) -> float:
    """Per configuration: mj_forward, contacts read, limits and singularity factors one by one."""
    from robot import kinematics as kin
    from sim.model import build_cell_model

    m, names = build_cell_model(cell, panel)
    d = mujoco.MjData(m)
    lo, hi = np.array(cell.model.q_min), np.array(cell.model.q_max)
    bad = 0
    t0 = time.perf_counter()
    for q in Q:
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        for c in d.contact[:d.ncon]:
            bad += c.dist < 0
        bad += int(np.any((q < lo) | (q > hi)))
        f = kin.singularity_factors(cell.model, q)
        bad += int(abs(f.wrist) < 0.05 or abs(f.elbow) < 0.05 or abs(f.shoulder) < 0.03)
    return time.perf_counter() - t0


def _panel_collision_rows() -> list[dict]:
    """The panel against the cell and itself, per fractional fold state (module docstring)."""
    from robot.cell import load_cell
    from sim.panel_collision import PanelCollider, check_panel_collisions

    rows = []
    for cell_file in ("ur5e_bench.toml", "ur10e_fold_table.toml"):
        cell = load_cell(ROOT / "cells" / cell_file)
        for fine in (False, True):
            panel = _panel(cell, fine)
            faces = [np.asarray(f) for f in _grid_faces(fine)]
            tris = np.array([[f[0], f[k], f[k + 1]] for f in faces for k in range(1, len(f) - 1)])
            tri_face = np.repeat(np.arange(len(faces)), [len(f) - 2 for f in faces])
            collider = PanelCollider(panel, tris, tri_face, cell.obstacles)
            out = {}

            def run():
                out["r"] = check_panel_collisions(collider)

            t = best_time(run, repeat=3)
            rows.append({"cell": cell.name, "faces": len(faces), "samples": out["r"].samples,
                         "contacts": len(out["r"].contacts), "panel_samples_per_s": out["r"].samples / t})
    return rows


def _grid_faces(fine: bool):
    import sys

    sys.path.insert(0, str(ROOT / "tests"))
    from fold_fixtures import grid_panel

    mesh = grid_panel(n_strips=6, n_columns=32, strip_width=0.1, length=0.5) if fine else grid_panel()
    return mesh.faces_list()


def _arm_arm_row() -> dict:
    """Arm against arm in the two-arm cell (module docstring)."""
    from robot.cell import load_cell
    from sim.arm_contacts import arm_arm_contacts
    from sim.model import build_cell_model

    cell = load_cell(ROOT / "cells" / "dual_ur10e.toml")
    rng = np.random.default_rng(0)
    M = 2000
    joints = {n: np.asarray(mount.home) + rng.normal(0.0, 0.3, (M, 6)) for n, mount in cell.arms}
    built = build_cell_model(cell, all_arms=True)
    out = {}
    t = best_time(lambda: out.update(hits=arm_arm_contacts(cell, joints, clearance=0.01, built=built)), repeat=3)
    m, names = build_cell_model(cell, all_arms=True)
    d = mujoco.MjData(m)
    rows = np.concatenate([joints[n] for n, _ in cell.arms], axis=1)

    def baseline():
        for k in range(M):
            d.qpos[:] = rows[k]
            mujoco.mj_kinematics(m, d)
            mujoco.mj_collision(m, d)
            for c in d.contact[:d.ncon]:
                _ = (c.geom[0], c.geom[1], c.dist)

    t_base = best_time(baseline, repeat=2)
    return {"configs": M, "contacts": len(out["hits"]), "configs_per_s": M / t, "baseline_per_s": M / t_base,
            "speedup": t_base / t}


def main() -> dict:
    from robot.cell import load_cell
    from sim.check import CheckSettings, check_program, interpolate_program
    from sim.check_events import collision_events, limit_events, singular_events
    from sim.model import build_cell_model
    from sim.programs import sweep_program

    rows = []
    cases = [("ur5e_bench.toml", False, 1, 0.08), ("ur5e_bench.toml", False, 4, 0.08),
             ("ur10e_fold_table.toml", False, 1, 0.08), ("ur10e_fold_table.toml", False, 4, 0.08),
             # the tool 1-2 cm over a 192-face panel: many mesh pairs inside the bounding spheres
             ("ur5e_bench.toml", True, 1, 0.025), ("ur10e_fold_table.toml", True, 1, 0.025)]
    for cell_file, fine, loops, height in cases:
        cell = load_cell(ROOT / "cells" / cell_file)
        panel = _panel(cell, fine)
        prog = sweep_program(cell, 2000, height=height, half_span=(0.06, 0.08), loops=loops, v=0.1)
        dense = interpolate_program(cell.model, prog, CheckSettings())
        M = len(dense.q)

        built = build_cell_model(cell, panel)  # once per cell; not part of the per-configuration rate

        def batched():
            collision_events(cell, panel, dense, built)
            limit_events(cell.model, dense)
            singular_events(cell.model, dense, CheckSettings())

        t_batched = best_time(batched, repeat=3)
        t_base = min(_baseline(cell, panel, dense.q) for _ in range(2))
        report_obj = {}

        def full():
            report_obj["r"], _ = check_program(prog, cell, panel)

        t_full = best_time(full, repeat=3)
        r = report_obj["r"]
        rows.append({
            "cell": cell.name, "faces": len(panel.pieces), "loops": loops, "waypoints": len(prog), "configs": M,
            "ok": r.ok, "configs_per_s": M / t_batched, "baseline_per_s": M / t_base,
            "speedup": t_base / t_batched, "build_s": best_time(lambda: build_cell_model(cell, panel)),
            "full_check_s": t_full,
            "full_configs_per_s": M / t_full,
        })
    panel_rows = _panel_collision_rows()
    arm_arm = _arm_arm_row()
    worst_rate = min(r["configs_per_s"] for r in rows if r["faces"] <= 15)
    worst_full = max(r["full_check_s"] for r in rows)
    fine_rate = min(r["configs_per_s"] for r in rows if r["faces"] > 15)
    meta = {"target_configs_per_s": 20000, "target_full_check_s": 1.0, "min_configs_per_s": worst_rate,
            "min_configs_per_s_192_faces_near_tool": fine_rate,
            "max_full_check_s": worst_full, "meets_targets": worst_rate >= 20000 and worst_full <= 1.0,
            "baseline": "per-configuration mj_forward + per-configuration limits/singularity calls",
            "panel_collision": panel_rows, "arm_arm": arm_arm,
            "min_panel_samples_per_s": min(r["panel_samples_per_s"] for r in panel_rows)}
    out = report("bench_check", rows, meta)
    for r in panel_rows:
        print(f"panel collisions: {r['cell']}, {r['faces']} faces, {r['samples']} fractional states: "
              f"{r['panel_samples_per_s']:,.0f} states/s ({r['contacts']} contacts)")
    print(f"arm against arm (dual_ur10e): {arm_arm['configs_per_s']:,.0f} configurations/s, baseline "
          f"{arm_arm['baseline_per_s']:,.0f}/s (x{arm_arm['speedup']:.1f})")
    print(f"min configs/s {worst_rate:,.0f} with a 15-face panel (target 20,000), {fine_rate:,.0f} with the tool "
          f"over a 192-face panel; slowest 2,000-waypoint check {worst_full:.3f} s (target 1 s)")
    return out


if __name__ == "__main__":
    main()
