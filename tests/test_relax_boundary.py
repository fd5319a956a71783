"""Boundary conditions of §2.5 on the tri-fold panel: free, fixed and the three extra rows of Fig. 9."""
import itertools

import numpy as np
import pytest

from fabkit import measures
from fabkit.generate import trifold_panel
from fabkit.relax import BOUNDARIES, relax
from fabkit.relax.boundary import add_boundary_row

TOL = 1e-8


@pytest.fixture(scope="module")
def trifold():
    return trifold_panel(resolution=16)


@pytest.fixture(scope="module")
def results(trifold):
    return {b: relax(trifold, boundary=b) for b in BOUNDARIES}


def test_trifold_needs_relaxing(trifold):
    assert np.abs(measures.interior_angle_defect(trifold)).max() > 1e-3


@pytest.mark.parametrize("boundary", BOUNDARIES)
def test_every_boundary_option_converges(trifold, results, boundary):
    res = results[boundary]
    assert res.converged, res.message
    out = res.mesh
    assert out.n_vertices == trifold.n_vertices and out.faces_list() == trifold.faces_list()
    assert set(out.face_data) == set(trifold.face_data)
    assert np.abs(measures.interior_angle_defect(out)).max() <= TOL
    assert measures.face_planarity(out).max() <= TOL
    assert res.max_displacement <= 0.5 * trifold.size   # relaxed, not reinvented


def test_fixed_boundary_keeps_the_boundary(trifold, results):
    b = trifold.boundary_vertex_mask
    assert np.array_equal(results["fixed"].mesh.vertices[b], trifold.vertices[b])
    assert not np.array_equal(results["free"].mesh.vertices[b], trifold.vertices[b])


def test_boundary_options_give_different_panels(trifold, results):
    scale = trifold.size
    for a, b in itertools.combinations(BOUNDARIES, 2):
        diff = np.linalg.norm(results[a].mesh.vertices - results[b].mesh.vertices, axis=1).max()
        assert diff > 1e-3 * scale, (a, b, diff)


@pytest.mark.parametrize("kind", ["row-in-plane", "row-out", "row-in"])
def test_boundary_row_makes_boundary_vertices_interior(trifold, kind):
    ext = add_boundary_row(trifold, kind)
    m = ext.mesh
    assert ext.n_original_vertices == trifold.n_vertices and ext.n_original_faces == trifold.n_faces
    assert np.array_equal(m.vertices[:trifold.n_vertices], trifold.vertices)
    assert m.faces_list()[:trifold.n_faces] == trifold.faces_list()
    assert np.all(m.interior_vertex_mask[:trifold.n_vertices][trifold.boundary_vertex_mask])
    assert np.all(m.boundary_vertex_mask[trifold.n_vertices:])
    row = m.vertices[trifold.n_vertices:] - trifold.vertices[np.flatnonzero(trifold.boundary_vertex_mask)]
    normals = np.linalg.norm(row, axis=1)
    assert np.allclose(normals, normals[0])          # one width for the whole row
    if kind == "row-in-plane":   # in-plane row keeps the angle sums near 2π at straight boundary parts
        d = np.abs(measures.angle_defect(m)[:trifold.n_vertices][trifold.boundary_vertex_mask])
        assert np.median(d) < 1e-6


def test_an_over_constraining_boundary_row_is_reported_with_a_hint():
    """Tri-fold at resolution 32 with 2 rows: the fixed row leaves a non-zero least-squares minimum."""
    tri = trifold_panel(resolution=32, rows=2)
    res = relax(tri, boundary="row-out", max_seconds=20)
    assert not res.converged
    assert "fixed boundary row (row-out)" in res.message and "try free" in res.message
    assert np.all(np.isfinite(res.mesh.vertices))
    assert relax(tri, boundary="free").converged
    stiff = relax(trifold_panel(resolution=16, rows=4), boundary="fixed", max_seconds=20)
    assert not stiff.converged and "a fixed boundary keeps every boundary vertex" in stiff.message
