"""Kept edge lengths in the relaxation: derivatives, a known answer, refusals and an infeasible request."""
import json

import numpy as np
import pytest

from fabkit import measures
from fabkit.errors import InputError
from fabkit.generate import reflect_panel
from fabkit.relax import RelaxOptions, Relaxer, relax
from fabkit.relax.energy import EnergyModel
from fabkit.relax.fd_gradient import colored_fd_gradient

from relax_meshes import perturbed
from test_relax_gradients import REL, _fd_gradient, _fd_jacobian, _mixed_mesh, _rel

TOL = 1e-8


@pytest.mark.parametrize("which", ["reflect", "mixed"])
@pytest.mark.parametrize("plane", ["cross", "covariance"])
def test_edge_term_gradient_and_jacobian_match_finite_differences(which, plane):
    mesh = perturbed(reflect_panel(columns=4, rows=2), 0.05, seed=3)[0] if which == "reflect" else _mixed_mesh()
    t = mesh.topology
    rng = np.random.default_rng(5)
    X = np.array(mesh.vertices)
    L = float(mesh.edge_lengths.mean())
    ids = np.flatnonzero(rng.random(mesh.n_edges) < 0.6)
    rest = mesh.edge_lengths[ids] * (1 + rng.normal(scale=0.05, size=len(ids)))  # residuals far from 0
    free = rng.random(mesh.n_vertices) < 0.8
    model = EnergyModel(t, defect_mask=t.interior_vertex_mask, free_mask=free, planarity_weight=0.7,
                        plane_method=plane, length_scale=L, edge_pairs=mesh.edges[ids], edge_rest=rest,
                        edge_weight=2.5)
    ev = model.evaluate(X)
    expected = np.linalg.norm(X[mesh.edges[ids, 0]] - X[mesh.edges[ids, 1]], axis=1) / rest - 1
    assert np.allclose(ev.edge_length, expected, rtol=0, atol=1e-15)
    h = 1e-6 * L
    assert _rel(ev.gradient, _fd_gradient(model, X, h)) <= REL
    assert np.all(ev.gradient[~free] == 0)
    r, J = model.residuals_and_jacobian(X)
    assert J.shape == (model.n_rows, 3 * int(free.sum()))
    assert _rel(J.toarray(), _fd_jacobian(model, X, h)) <= REL
    # the residual vector carries the whole energy, edge rows included: E = ½‖r‖²
    assert 0.5 * r @ r == pytest.approx(ev.energy, rel=1e-12)
    assert np.allclose(r[-len(ids):], np.sqrt(2.5) * expected, rtol=0, atol=1e-15)
    # the edge term alone (planarity and defect rows unchanged) is what changed
    plain = EnergyModel(t, defect_mask=t.interior_vertex_mask, free_mask=free, planarity_weight=0.7,
                        plane_method=plane, length_scale=L)
    assert ev.energy - plain.energy(X) == pytest.approx(0.5 * 2.5 * expected @ expected, rel=1e-10)
    if free.all() or which == "reflect":
        assert _rel(colored_fd_gradient(model, X), ev.gradient) <= 1e-5


def test_kept_boundary_edges_reach_their_lengths_known_answer():
    """Perturbed reflect panel, boundary edges kept at their unperturbed lengths: relaxes to the
    tolerances and those edges have exactly the requested lengths."""
    truth = reflect_panel(columns=12, rows=3)
    noisy, sigma = perturbed(truth, 0.01, seed=11)
    b = np.flatnonzero(truth.topology.boundary_edge_mask)
    rest = truth.edge_lengths[b]
    assert np.abs(noisy.edge_lengths[b] / rest - 1).max() > 1e-3        # the noise really moved them
    for method in ("dr", "newton", "lbfgs"):
        res = relax(noisy, method=method, edge_lengths=(b, rest))
        assert res.converged, (method, res.message)
        assert res.max_defect <= TOL and res.max_planarity <= TOL
        k = np.abs(measures.interior_angle_defect(res.mesh))
        assert k.max() <= TOL and measures.face_planarity(res.mesh).max() <= TOL
        err = np.abs(res.mesh.edge_lengths[b] / rest - 1)
        assert err.max() <= TOL and res.max_edge_length_error == pytest.approx(err.max(), abs=1e-15)
        assert "max edge-length error" in res.message
        assert np.linalg.norm(res.mesh.vertices - truth.vertices, axis=1).max() <= 6 * sigma
        assert res.history[-1].max_edge_length <= TOL
        report = json.loads(json.dumps(res.to_report(per_element=False)))
        assert report["final"]["max_edge_length_error"] <= TOL
        assert report["options"]["edge_lengths"][0] == [int(b[0]), float(rest[0])]


def test_mapping_form_and_no_edges_leave_behaviour_unchanged():
    truth = reflect_panel(columns=8, rows=2)
    noisy, _ = perturbed(truth, 0.01, seed=4)
    plain = relax(noisy)
    empty = relax(noisy, edge_lengths=())
    assert np.array_equal(plain.mesh.vertices, empty.mesh.vertices) and plain.message == empty.message
    assert plain.max_edge_length_error == 0.0 and "edge-length" not in plain.message
    ids = np.flatnonzero(truth.topology.boundary_edge_mask)[:5]
    as_map = RelaxOptions(edge_lengths={int(e): float(truth.edge_lengths[e]) for e in ids})
    as_pair = RelaxOptions(edge_lengths=(ids, truth.edge_lengths[ids]))
    assert as_map.edge_lengths == as_pair.edge_lengths
    assert RelaxOptions(edge_lengths=as_map.edge_lengths).edge_lengths == as_map.edge_lengths


def test_infeasible_lengths_report_did_not_converge_without_nan():
    """A quad's four sides kept at lengths no quad can have (one side longer than the other three)."""
    truth = reflect_panel(columns=6, rows=2)
    noisy, _ = perturbed(truth, 0.01, seed=2)
    t = truth.topology
    face = t.face(0)
    E = {tuple(sorted(e)): i for i, e in enumerate(truth.edges.tolist())}
    sides = [E[tuple(sorted((int(face[i]), int(face[(i + 1) % 4]))))] for i in range(4)]
    lengths = truth.edge_lengths[sides].copy()
    lengths[0] = 4.0 * lengths[1:].sum()                                   # violates the polygon inequality
    res = relax(noisy, edge_lengths=(sides, lengths), max_iter=400, newton_max_iter=20)
    assert not res.converged
    assert res.message.startswith("did not converge") and "max edge-length error" in res.message
    assert np.all(np.isfinite(res.mesh.vertices)) and np.isfinite(res.max_edge_length_error)
    assert res.max_edge_length_error > 0.1


@pytest.mark.parametrize("spec,match", [
    (([0, 1], [1.0]), "2 edge ids but 1 lengths"),
    (([0, 1], [1.0, np.nan]), "length of edge 1"),
    (([0, 1], [1.0, 0.0]), "length of edge 1"),
    (([0, 1], [1.0, -2.0]), "length of edge 1"),
    (([0.5], [1.0]), "non-negative integers"),
    (([-1], [1.0]), "non-negative integers"),
    (([3, 3], [1.0, 1.0]), "given twice"),
    ({0: "a"}, "numbers"),
])
def test_bad_edge_length_specs_are_input_errors(spec, match):
    with pytest.raises(InputError, match=match):
        RelaxOptions(edge_lengths=spec)


def test_edge_id_out_of_range_is_an_input_error():
    mesh = reflect_panel(columns=4, rows=2)
    with pytest.raises(InputError, match=f"edge {mesh.n_edges} does not exist"):
        Relaxer(mesh, edge_lengths=([mesh.n_edges], [1.0]))
    with pytest.raises(ValueError, match="edge_length_weight"):
        RelaxOptions(edge_length_weight=0.0)
