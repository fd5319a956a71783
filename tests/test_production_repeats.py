"""Panels that are the same part share one refold, program and check; each panel still gets its files."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fabkit.generate.pleated import pleated_vault
from fabkit.panels.layout import layout_panels
from fabkit.panels.repeats import SAME_PART_TOL, rigid_residual, same_part_classes
from fabkit.panels.surface import GridSurface, grid_from_topology

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / "cells" / "ur5e_bench.toml"


def _layout():
    """10 bands of 2 panels: band b and b + 4 are the same parts (the reflection method's period)."""
    mesh = pleated_vault(rows=10, length=2.5, radius=0.6, arc=np.radians(60.0), columns=8, rows_per_band=8)
    index, _ = grid_from_topology(mesh)
    return layout_panels(GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), cols=2, columns_per_panel=4)


def test_rigid_residual_is_zero_for_a_rigid_motion_and_refuses_a_mirror():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(30, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    R = q * np.sign(np.linalg.det(q))
    assert rigid_residual(a, a @ R.T + [1.0, -2.0, 0.5]) < 1e-12
    assert rigid_residual(a, a * [-1.0, 1.0, 1.0]) > 0.1  # a mirror image is another part


def test_classes_group_within_the_tolerance_only():
    rng = np.random.default_rng(2)
    flat = rng.normal(size=(12, 2))
    target = rng.normal(size=(12, 3))
    exact = {"faces": np.arange(8).reshape(2, 4)}
    parts = {0: {"exact": exact, "flat": flat, "target": target},
             1: {"exact": exact, "flat": flat + [0.5 * SAME_PART_TOL, 0.0], "target": target + 3.0},
             2: {"exact": exact, "flat": flat + [3.0 * SAME_PART_TOL, 0.0], "target": target},
             3: {"exact": {"faces": np.arange(8).reshape(2, 4)[:, ::-1]}, "flat": flat, "target": target}}
    c = same_part_classes(parts)
    assert c.rep == {0: 0, 1: 0, 2: 2, 3: 3}
    assert c.deviation[1] == pytest.approx(0.5 * SAME_PART_TOL, rel=1e-6)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The run sharing results by part, and every panel that got another's results recomputed alone."""
    from fabkit.panels.production import ProductionOptions, program_task, refold_and_program, run_production, stock
    from sim.production import carry_over, program_panel

    tmp = tmp_path_factory.mktemp("repeats")
    layout = _layout()
    kw = dict(cell_toml=CELL.read_text(), cell_name=CELL.name, program=program_panel, timeout=600)
    # band 1 and its repeat, band 5 (the rest "not selected", to keep the test short)
    select = {p.name for p in layout.panels if p.band in (1, 5)}
    shared = run_production(layout, tmp / "shared", carry=carry_over, jobs=2, select=select, **kw)
    own = {}
    for p in layout.panels:
        if p.name in shared.same_as:
            task = program_task(p, shared.geometry.results[p.id], ProductionOptions(), kw["cell_toml"], CELL.name,
                                stock(), program_panel)
            own[p.name] = refold_and_program(task)
    return {"layout": layout, "shared": shared, "own": own, "tmp": tmp}


@pytest.mark.slow
def test_a_shared_result_equals_the_recomputed_one(runs):
    from fabkit.io.fold import load_fold

    shared, own, tmp = runs["shared"], runs["own"], runs["tmp"]
    assert len(shared.panels) == 24 and len(shared.same_as) == 2  # 4 selected: band 5 repeats band 1 (measured)
    assert len(shared.recomputed["refold_program_check"]) == 4  # every selected panel has its results
    entries = json.loads((tmp / "shared" / "manifest.json").read_text())["panels"]
    for a in shared.panels:
        if a.name not in shared.same_as:
            continue
        rep, b = shared.same_as[a.name], own[a.name]
        assert entries[a.name]["same_as"] == rep and entries[a.name]["same_part_deviation_m"] <= SAME_PART_TOL
        assert a.stage == b["stage"]
        if "refold" not in a.files:
            assert b["fold"] is None
            continue
        fa = load_fold(tmp / "shared" / a.files["refold"])
        (tmp / f"{a.name}_own.fold").write_text(b["fold"])
        fb = load_fold(tmp / f"{a.name}_own.fold")
        doc = json.loads((tmp / "shared" / a.files["refold"]).read_text())
        assert doc["fabkit:panel"] == a.name and doc["fabkit:fold_states_of"] == rep
        assert len(fa.frames) == len(fb.frames)
        for sa, sb in zip(fa.frames, fb.frames):  # the fold states as recomputed, within the tolerance
            assert np.linalg.norm(sa.vertices_coords - sb.vertices_coords, axis=1).max() <= SAME_PART_TOL
        if "program" not in a.files:
            assert b["toolpath"] is None
            continue
        pa, pb = json.loads((tmp / "shared" / a.files["program"]).read_text()), b["toolpath"]
        assert pa["source"]["file"] == Path(a.files["refold"]).name
        qa = np.array([w["q"] for w in pa["waypoints"]])
        qb = np.array([w["q"] for w in pb["waypoints"]])
        assert qa.shape == qb.shape and np.abs(qa - qb).max() < 1e-6  # rad
        assert pa["cycle_time_s"] == pytest.approx(pb["cycle_time_s"], abs=1e-6)
        ca, cb = json.loads((tmp / "shared" / a.files["check"]).read_text()), b["check"]
        assert ca["toolpath_sha256"] == pa["sha256"] and ca["ok"] == cb["ok"]
        assert [(p["kind"], p["waypoint"]) for p in ca["problems"]] == [(p["kind"], p["waypoint"]) for p in cb["problems"]]
        if cb["min_clearance_m"] is not None:
            assert ca["min_clearance_m"] == pytest.approx(cb["min_clearance_m"], abs=1e-6)
        assert any(rep in n for n in ca["notes"])


@pytest.mark.slow
def test_a_shared_check_is_the_check_of_the_panels_own_files(runs):
    """`fabkit check` of a panel that got its part's results reproduces its CHECK.json."""
    from robot.cell import load_cell
    from sim.check import check_toolpath

    shared, tmp = runs["shared"], runs["tmp"]
    carried = [p for p in shared.panels if p.name in shared.same_as and "check" in p.files]
    assert carried
    p = carried[0]
    report = check_toolpath(tmp / "shared" / p.files["program"], load_cell(CELL), thickness=1.0e-3)
    stored = json.loads((tmp / "shared" / p.files["check"]).read_text())
    assert report.ok == stored["ok"] and report.toolpath_sha256 == stored["toolpath_sha256"]
    assert report.cycle_time_s == pytest.approx(stored["cycle_time_s"])
    assert [q.to_json() for q in report.problems] == stored["problems"]
    assert report.min_clearance_m == stored["min_clearance_m"]
