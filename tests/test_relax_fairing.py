"""Crease fairing (RelaxOptions.crease_fairness): exact operators, then noisy reflect panels with known answers."""
import numpy as np
import pytest

from fabkit import measures
from fabkit.generate import reflect_panel
from fabkit.relax import Relaxer, relax
from fabkit.relax.fairing import _Extended, crease_chains, third_differences

from relax_meshes import REFLECT_PANELS, crease_edges, folded_grid, perturbed

TOL = 1e-8
PANELS = {**REFLECT_PANELS, "24x12": dict(columns=24, rows=12)}


def test_third_differences_vanish_on_quadratics_and_wrap_on_loops():
    t = np.linspace(-1.0, 2.0, 9)
    P = np.stack([t, 3 * t ** 2 - t, 0.5 - 2 * t ** 2], axis=1)        # a parabola: Δ³ = 0 exactly
    D = third_differences([np.arange(9)], 9)
    assert D.shape == (6, 9)
    assert np.abs(D @ P).max() <= 1e-12
    cubic = np.stack([t ** 3, t, 0 * t], axis=1)                      # Δ³ t³ = 6 h³ on every row
    h = t[1] - t[0]
    assert np.allclose((D @ cubic)[:, 0], 6 * h ** 3)
    loop = third_differences([np.array([0, 1, 2, 3, 4, 0])], 5)         # closed: one row per vertex
    assert loop.shape == (5, 5) and np.allclose(loop.sum(axis=1), 0)
    assert np.array_equal(np.sort(loop.indices[loop.indptr[3]:loop.indptr[4]]), [0, 1, 3, 4])
    assert third_differences([np.array([0, 1, 2])], 3).shape == (0, 3)   # too short: no row


def test_third_differences_scale_with_the_crease_resolution():
    t = np.linspace(0.0, 1.0, 25)                                  # 24 equal segments: h_ref = 2 h
    P = np.stack([t, 0 * t, 0 * t], axis=1)
    D = third_differences([np.arange(25)], 25, P)
    assert np.allclose(np.abs(D.data).reshape(-1, 4) / [1, 3, 3, 1], 4.0)   # (h_ref / h)² = 4


def test_crease_chains_stop_at_corners_of_the_design():
    from fabkit.generate import grid_faces
    from fabkit.mesh import PolyMesh

    n = 7                                                          # 6 x 6 quads, an L-shaped crease
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float), indexing="ij")
    V = np.stack([x, y, 0 * x], axis=-1).reshape(-1, 3)
    faces = grid_faces(n - 1, n)
    centre = V[faces].mean(axis=1)
    strip = ((centre[:, 0] < 3) & (centre[:, 1] < 3)).astype(np.int64)
    mesh = PolyMesh(V, faces, face_data={"strip": strip})
    chains = crease_chains(mesh)
    corner = 3 * n + 3
    assert len(chains) == 2 and all(len(c) == 4 for c in chains)
    assert all(corner in (c[0], c[-1]) for c in chains)             # split at the 90° corner, shared
    assert len(crease_chains(mesh, kink_angle=np.radians(120))) == 1   # a blunter threshold keeps one


def test_crease_chains_follow_strip_tags_or_folded_edges():
    one = reflect_panel(**PANELS["one-crease"])
    chains = crease_chains(one)
    assert len(chains) == 1 and len(chains[0]) == 13                      # one vertex per generator
    assert set(chains[0].tolist()) == set(one.edges[crease_edges(one)].reshape(-1).tolist())
    assert len(crease_chains(reflect_panel(**PANELS["two-creases"]))) == 2
    folded = folded_grid()                                                # untagged: the 0.8 rad fold
    (chain,) = crease_chains(folded)
    assert np.allclose(folded.vertices[chain, 0], 0.5)


def test_fairness_rows_jacobian_matches_finite_differences():
    noisy, _ = perturbed(reflect_panel(**PANELS["one-crease"]), 0.01, seed=1)
    solver = Relaxer(noisy, crease_fairness=10.0)
    ext = _Extended(solver.model, solver.fairness_operator, 10.0, noisy.vertices)
    z = ext.start(noisy.vertices) + np.random.default_rng(0).normal(scale=1e-3, size=ext.n_y + ext.n_s)
    r, J = ext.residuals(z, noisy.vertices)
    h = 1e-7
    cols = np.random.default_rng(1).choice(len(z), 40, replace=False)
    for c in cols:
        e = np.zeros_like(z)
        e[c] = h
        fd = (ext.residuals(z + e, noisy.vertices, False)[0] - ext.residuals(z - e, noisy.vertices, False)[0]) / (2 * h)
        col = J[:, c].toarray().ravel()
        assert np.abs(fd - col).max() <= 1e-6 * max(1.0, np.abs(col).max())


def _dihedral_change_deg(truth, mesh):
    ce = crease_edges(truth)
    return np.degrees(np.abs(measures.dihedral_angles(mesh)[ce] - measures.dihedral_angles(truth)[ce]))


@pytest.mark.parametrize("name", sorted(PANELS))
@pytest.mark.parametrize("seed", [0, 5, 11])
def test_fairing_keeps_every_crease_fold_within_one_degree_at_one_percent_noise(name, seed):
    truth = reflect_panel(**PANELS[name])
    noisy, sigma = perturbed(truth, 0.01, seed=seed)
    res = relax(noisy, crease_fairness=10.0)
    assert res.converged, res.message
    assert "fair" in res.phase_iterations and "crease fairing converged" in res.message
    k = np.abs(measures.interior_angle_defect(res.mesh)).max()
    assert k <= TOL and measures.face_planarity(res.mesh).max() <= TOL
    assert np.linalg.norm(res.mesh.vertices - truth.vertices, axis=1).max() <= 6 * sigma
    change = _dihedral_change_deg(truth, res.mesh)
    assert change.max() <= 1.0                                   # measured 0.11-0.41 deg
    plain = relax(noisy, crease_fairness=0.0)
    assert change.mean() < _dihedral_change_deg(truth, plain.mesh).mean()


@pytest.mark.parametrize("name", ["one-crease", "two-creases", "skewed"])
def test_fairing_at_three_percent_noise_converges_near_the_panel(name):
    truth = reflect_panel(**PANELS[name])
    noisy, sigma = perturbed(truth, 0.03, seed=0)
    res = relax(noisy, crease_fairness=10.0)
    assert res.converged, res.message
    assert np.linalg.norm(res.mesh.vertices - truth.vertices, axis=1).max() <= 6 * sigma
    assert _dihedral_change_deg(truth, res.mesh).max() <= 2.0     # unfaired: 4.7-5.5 deg (docs/relax.md)


def test_fairing_leaves_exact_panels_alone_barely_moves_near_ones_and_honours_fixed_vertices_and_rows():
    for kw in PANELS.values():
        truth = reflect_panel(**kw)
        exact = relax(truth)                                      # fairing is on by default
        assert exact.converged and exact.iterations == 0 and np.array_equal(exact.mesh.vertices, truth.vertices)
        near, _ = perturbed(truth, 1e-4, seed=1)                  # nearly exact: the faired crease stays put
        res = relax(near)
        assert res.converged and "crease fairing converged" in res.message
        L = float(truth.edge_lengths.mean())
        assert np.linalg.norm(res.mesh.vertices - truth.vertices, axis=1).max() <= 2e-2 * L   # measured <= 1.4 %
        assert _dihedral_change_deg(truth, res.mesh).max() <= 0.1                              # measured <= 0.07 deg
    noisy, sigma = perturbed(reflect_panel(**PANELS["one-crease"]), 0.01, seed=3)
    fixed = [0, 20, 33]
    held = relax(noisy, crease_fairness=10.0, fixed=fixed)
    assert held.converged and np.array_equal(held.mesh.vertices[fixed], noisy.vertices[fixed])
    row = relax(noisy, crease_fairness=10.0, boundary="row-in-plane")
    assert row.converged and row.mesh.n_vertices == noisy.n_vertices


def test_fairing_without_creases_says_so():
    flat = folded_grid(fold=0.0)
    noisy, _ = perturbed(flat, 0.01, seed=2)
    res = relax(noisy, crease_fairness=10.0)
    assert res.converged and "crease fairing skipped" in res.message
    with pytest.raises(ValueError, match="crease_fairness"):
        relax(noisy, crease_fairness=-1.0)
