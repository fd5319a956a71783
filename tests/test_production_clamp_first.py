"""A production set-up whose clamp footprint leaves the clamped face is refused before it is planned,
with the problem the full check names for it (the same verdict, without the plan and the check)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fabkit.generate.pleated import pleated_vault
from fabkit.panels.layout import layout_panels
from fabkit.panels.production import ProductionOptions, program_task, refold_and_program, stock
from fabkit.panels.surface import GridSurface, grid_from_topology
from fabkit.panels.workflow import PanelsOptions, run_panels

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / "cells" / "ur5e_bench.toml"
JAW = "footprint = [[-0.012, -0.008], [0.012, -0.008], [0.012, 0.008], [-0.012, 0.008]]"


@pytest.fixture(scope="module")
def panel():
    from sim.production import program_panel

    mesh = pleated_vault(rows=2, length=0.5, radius=0.6, arc=np.radians(60.0), fold=np.radians(40.0), columns=8,
                         rows_per_band=8)
    index, _ = grid_from_topology(mesh)
    layout = layout_panels(GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), cols=2,
                           columns_per_panel=4)
    geo = run_panels(layout, PanelsOptions())
    p = layout.panels[0]
    task = program_task(p, geo.results[p.id], ProductionOptions(), CELL.read_text(), CELL.name, stock(), program_panel)
    res = refold_and_program(task)
    assert res["stage"] is None, res["reason"]
    return res


@pytest.mark.slow
def test_a_jaw_off_the_face_is_refused_before_planning_as_the_check_refuses_it(panel, monkeypatch):
    import sim.production as production

    text = CELL.read_text()
    assert JAW in text
    wide = text.replace(JAW, "footprint = [[-0.06, -0.04], [0.06, -0.04], [0.06, 0.04], [-0.06, 0.04]]")
    args = (panel["fold"], "p_refold.fold", wide, CELL.name, 1.0e-3)
    first = production.program_panel(*args, grip_face=panel["grip_face"])
    assert first["stage"] == "check" and first["toolpath"] is None and first["check"] is None
    assert "leaves clamped face" in first["unclampable"] and first["unclampable"] in first["reason"]
    # without the clamp check first: planned and checked in full, and the check names the same problem
    monkeypatch.setattr(production, "clamp_refusal", lambda *a: None)
    full = production.program_panel(*args, grip_face=panel["grip_face"])
    assert full["stage"] == "check" and full["check"] is not None
    details = [q["detail"] for q in full["check"]["problems"] if q["kind"] == "holds"]
    assert first["unclampable"] in details


@pytest.mark.slow
def test_the_bench_jaw_on_the_panel_is_not_refused(panel, tmp_path):
    from sim.production import clamp_refusal

    path = tmp_path / "p_refold.fold"
    path.write_text(panel["fold"])
    from robot.cell import load_cell

    assert clamp_refusal(path, load_cell(CELL)) is None
    assert panel["check"]["ok"] and not any("clamp" in q["detail"] for q in panel["check"]["problems"])
