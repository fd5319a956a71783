"""Multi-panel workflow: surface, arcs, staggered layout, congruency feedback, symmetry, executors."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from fabkit.errors import InputError
from fabkit.generate.polyhedra import grid
from fabkit.io.obj import save_obj
from fabkit.mesh import PolyMesh
from fabkit.panels.congruency import measure_congruency
from fabkit.panels.layout import layout_panels
from fabkit.panels.surface import canopy_lowpoly, grid_from_topology, subdivide_grid
from fabkit.panels.workflow import PanelsOptions, mirror_partner, run_panels


@pytest.fixture(scope="module")
def surface():
    return subdivide_grid(canopy_lowpoly(stations=8), 3)


@pytest.mark.parametrize("levels", [1, 2, 3, 4])
def test_arcs_are_planar_curves(levels):
    """Every iso-line across a 3-vertex-wide low-poly is planar after subdivision (3 control points)."""
    S = subdivide_grid(canopy_lowpoly(), levels)
    P = S.points
    for j in range(P.shape[1]):
        X = P[:, j] - P[:, j].mean(axis=0)
        n = np.linalg.svd(X)[2][-1]
        assert np.abs(X @ n).max() < 1e-12
    # most arcs are swept (not trivially planar in an x = const plane); the sweep is 0 only where
    # sin(2 pi x / length) vanishes (ends and middle)
    spread = np.ptp(P[:, :, 0], axis=0)
    assert (spread > 1e-3).mean() > 0.7


def test_surface_is_mirror_symmetric(surface):
    P = surface.points
    assert np.abs(P[:, ::-1] * [-1, 1, 1] - P).max() < 1e-12


@pytest.mark.parametrize("rows,cols,expected", [
    (2, 3, 2),     # one aligned pair: cols - 1 interior four-panel corners
    (6, 2, 1 + 2 + 1),  # pairs offset 0, 1, 0: (cols-1) + cols + (cols-1)
    (6, 4, 3 + 4 + 3),
    (14, 7, 4 * 6 + 3 * 7),
])
def test_singularity_points_count(surface, rows, cols, expected):
    L = layout_panels(surface, rows=rows, cols=cols, columns_per_panel=4)
    assert len(L.singular_keys) == expected
    n_offset = sum(int(o) for o in L.pair_offsets)
    assert len(L.panels) == (rows // 2 - n_offset) * 2 * cols + n_offset * 2 * (cols + 1)
    # every singularity point is a corner of exactly four panels and fixed in each of them
    for key in L.singular_keys:
        holders = [p for p in L.panels if key in p.keys.ravel()]
        assert len(holders) == 4
        assert all(p.fixed[list(p.keys.ravel()).index(key)] for p in holders)


def test_neighbours_share_boundary_vertices_exactly(surface):
    L = layout_panels(surface, rows=6, cols=3, columns_per_panel=4)
    points = {}
    for p in L.panels:
        for k, v in zip(p.keys.ravel(), p.mesh.vertices):
            if k in points:
                assert np.array_equal(points[k], v)
            points[k] = v
    c = measure_congruency(L.shared_edges, [p.mesh.edges for p in L.panels], [p.mesh.vertices for p in L.panels])
    assert len(c.relative) > 0 and c.max_relative == 0.0
    # side edges and arc edges are both shared
    assert len(L.shared_edges) > 50


def test_layout_rejects_bad_parameters(surface):
    with pytest.raises(InputError, match="even"):
        layout_panels(surface, rows=5)
    with pytest.raises(InputError, match="columns per panel"):
        layout_panels(surface, rows=2, columns_per_panel=3)


def test_grid_from_topology_recovers_grid_and_refuses_non_grids():
    m = grid(4, 2)
    index, lowpoly = grid_from_topology(m)
    assert index.shape == (3, 5) and lowpoly
    assert sorted(index.ravel().tolist()) == list(range(m.n_vertices))
    tri = PolyMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(InputError, match="quad"):
        grid_from_topology(tri)


@pytest.fixture(scope="module")
def small_run(surface):
    # shared edges not kept: panels relaxed fully independently, so the 2D feedback has work to do
    L = layout_panels(surface, rows=6, cols=2, columns_per_panel=4)
    return run_panels(L, PanelsOptions(max_rounds=6, tol_congruency=1e-12, keep_shared_edges=False))


def test_kept_shared_edges_make_neighbours_agree_before_any_merge(surface):
    """Default: every panel is relaxed with its shared boundary edges kept at their lengths on the
    common input surface, so neighbours agree in 3D and the first unfold is already congruent."""
    L = layout_panels(surface, rows=6, cols=2, columns_per_panel=4)
    run = run_panels(L, PanelsOptions())
    assert all(r.converged for r in run.results), [r.message for r in run.results if not r.converged]
    assert all(r.max_defect <= 1e-8 and r.max_planarity <= 1e-8 and r.flipped == 0 for r in run.results)
    assert len(run.rounds) == 1 and run.ok
    assert run.rounds[0]["max_incongruency"] <= 1e-7
    assert max(r.unfold_max for r in run.results) <= 1e-6
    # the kept edges really have their input lengths in 3D
    for pa, ea, pb, eb in L.shared_edges:
        la = np.linalg.norm(np.subtract(*run.results[pa].relaxed[L.panels[pa].mesh.edges[ea]]))
        lb = np.linalg.norm(np.subtract(*run.results[pb].relaxed[L.panels[pb].mesh.edges[eb]]))
        l0 = L.panels[pa].mesh.edge_lengths[ea]
        assert abs(la / l0 - 1) <= 1e-8 and abs(lb / l0 - 1) <= 1e-8


def test_feedback_reduces_incongruency_geometrically(small_run):
    inc = [r["max_incongruency"] for r in small_run.rounds]
    assert len(inc) == 7
    assert inc[0] > 1e-4  # independent relaxation (shared edges not kept) leaves real mismatch
    assert all(b < 0.8 * a for a, b in zip(inc[1:], inc[2:]))  # each round cuts it down
    assert inc[-1] < inc[0] / 20
    assert all(r.converged for r in small_run.results)
    assert all(r.max_defect <= 1e-8 and r.max_planarity <= 1e-8 for r in small_run.results)
    assert all(r.flipped == 0 for r in small_run.results)


def test_failing_panels_are_named(small_run):
    failing = small_run.failing_panels()
    assert not small_run.ok and failing
    assert all("incongruency" in why or "unfold" in why for _, why in failing)


def test_symmetric_run_is_mirror_exact(surface):
    L = layout_panels(surface, rows=6, cols=2, columns_per_panel=4)
    run = run_panels(L, PanelsOptions(max_rounds=2, symmetric=True))
    partner = mirror_partner(L)
    for p in L.panels:
        q = L.panels[partner[p.id]]
        a, b = run.results[p.id], run.results[q.id]
        nr, nc = len(p.rows), len(p.stations)
        perm = np.arange(nr * nc).reshape(nr, nc)[::-1].ravel()
        assert np.array_equal(a.relaxed, b.relaxed[perm] * np.array([-1.0, 1.0, 1.0]))
        assert np.array_equal(a.uv, b.uv[perm] * np.array([-1.0, 1.0]))
        assert a.flipped == 0 and b.flipped == 0
    # the mirror costs nothing in accuracy: the unmirrored solve is symmetric to the solver tolerance
    full = run_panels(L, PanelsOptions(max_rounds=0))
    for p in L.panels:
        q = L.panels[partner[p.id]]
        nr, nc = len(p.rows), len(p.stations)
        perm = np.arange(nr * nc).reshape(nr, nc)[::-1].ravel()
        assert np.abs(full.results[p.id].relaxed - full.results[q.id].relaxed[perm] * [-1, 1, 1]).max() < 1e-6


@pytest.mark.slow
def test_serial_pool_and_dask_give_identical_results(surface):
    from distributed import LocalCluster

    L = layout_panels(surface, rows=6, cols=2, columns_per_panel=4)
    opts = PanelsOptions(max_rounds=1, tol_congruency=1e-12)  # one merge round exercises the targets path
    serial = run_panels(L, opts, jobs=1)
    pooled = run_panels(L, opts, jobs=2)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        dasked = run_panels(L, opts, scheduler=cluster.scheduler_address)
    for a, b, c in zip(serial.results, pooled.results, dasked.results):
        assert np.abs(a.relaxed - b.relaxed).max() <= 1e-12 and np.abs(a.relaxed - c.relaxed).max() <= 1e-12
        assert np.abs(a.uv - b.uv).max() <= 1e-12 and np.abs(a.uv - c.uv).max() <= 1e-12


def test_cli_writes_everything_and_exit_codes(tmp_path):
    src = tmp_path / "canopy.obj"
    save_obj(canopy_lowpoly(stations=8), src)
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "fabkit", "panels", str(src), "-o", str(out), "--rows", "6", "--cols",
                        "2", "--columns-per-panel", "4", "--levels", "3", "--max-rounds", "2", "--report",
                        str(tmp_path / "r.json"), "--no-plots"], capture_output=True, text=True, timeout=300)
    assert r.returncode in (0, 1), r.stderr
    import json

    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["panels"] == 14 and rep["singularity_points"] == 4
    names = [p["name"] for p in rep["per_panel"]]
    for name in names:
        for suffix in (".obj", "_flat.obj", ".fold", ".dxf", ".svg"):
            assert (out / "panels" / f"{name}{suffix}").is_file()
    if r.returncode == 1:
        assert rep["failing_panels"] and "miss a tolerance" in r.stdout
    # bad input: one line, exit 2, nothing written
    bad = tmp_path / "tri.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    r = subprocess.run([sys.executable, "-m", "fabkit", "panels", str(bad), "-o", str(tmp_path / "nope")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "tri.obj" in r.stderr
    assert not (tmp_path / "nope").exists()
