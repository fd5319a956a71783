"""Springback-compensated fold states on real refold output (reflect panels, a straight crease)."""
import math
from dataclasses import replace

import numpy as np
import pytest

from fabkit.fold import FoldModel
from fabkit.materials import get_material
from fabkit.refold import refold
from fabkit.refold.export import to_fold_model
from fabkit.sheet import BendRadiusError, SpringbackError, programmed_angle, sheet_spec
from fabkit.sheet.compensate import compensate_sequence
from fabkit.sheet.creases import panel_creases
from tests.refold_panels import reflect_pair, straight_crease_pair

MM = 1e-3
DEG = math.pi / 180


@pytest.fixture(scope="module")
def reflect_seq():
    flat, target = reflect_pair(2, columns=12, rows=3)
    return to_fold_model(refold(flat, target, frames=4))


@pytest.fixture(scope="module")
def straight_seq():
    flat, target = straight_crease_pair(90 * DEG)
    return to_fold_model(refold(flat, target, frames=3, drive="all"))


def test_rigid_material_returns_the_input_exactly(reflect_seq):
    c = compensate_sequence(reflect_seq, sheet_spec(get_material("none"), None))
    assert c.model is reflect_seq
    np.testing.assert_array_equal(c.programmed, c.design)


def test_programmed_angles_exceed_design_by_the_model_amount(reflect_seq):
    spec = sheet_spec(get_material("5052-H32"), 1 * MM)
    c = compensate_sequence(reflect_seq, spec)
    creases = panel_creases(reflect_seq)
    assert [k.name for k in creases] == ["crease 0", "crease 1"]
    assert all(k.kappa_g > 0 for k in creases)  # curved creases: the panel term is in
    last = len(c.design) - 1
    for k in creases:
        for e in k.edges:
            d = c.design[last, e]
            want = programmed_angle(spec, d, k.kappa_g, k.panel_width)
            assert c.programmed[last, e] == pytest.approx(want, abs=1e-12)
            assert abs(c.programmed[last, e]) > abs(d) + 0.5 * DEG  # overbent, sign kept
            assert np.sign(c.programmed[last, e]) == np.sign(d)
    # the FOLD keeps the design: key frame and design angles untouched, the states moved
    assert np.array_equal(c.model.edges_fold_angle, reflect_seq.edges_fold_angle)
    V0 = np.asarray(reflect_seq.frames[last].vertices_coords)
    V1 = np.asarray(c.model.frames[last].vertices_coords)
    assert np.abs(V1 - V0).max() > 1 * MM
    # every compensated state is still an isometric fold of the flat pattern
    ev = np.asarray(c.model.edges_vertices)
    L0 = np.linalg.norm(np.diff(np.asarray(c.model.vertices_coords)[ev], axis=1)[:, 0], axis=1)
    L1 = np.linalg.norm(np.diff(V1[ev], axis=1)[:, 0], axis=1)
    assert np.abs(L1 / L0 - 1).max() < 1e-9
    table = c.state_table()
    assert table[last]["creases"][0]["programmed_deg"] > table[last]["creases"][0]["design_deg"]


def test_negligible_springback_reproduces_the_design_states(reflect_seq):
    spec = sheet_spec(replace(get_material("5052-H32"), calibration=1e-12), 1 * MM)
    c = compensate_sequence(reflect_seq, spec)
    for s in range(reflect_seq.n_frames):
        np.testing.assert_allclose(c.model.frames[s].vertices_coords, reflect_seq.frames[s].vertices_coords,
                                   atol=1e-9)


def test_straight_crease_overbend_is_design_over_k(straight_seq):
    spec = sheet_spec(get_material("5052-H32"), 1.6 * MM, inside_radius=1.6 * MM)
    c = compensate_sequence(straight_seq, spec)
    (k,) = panel_creases(straight_seq)
    assert k.kappa_g == pytest.approx(0.0, abs=1e-9)
    last = len(c.design) - 1
    np.testing.assert_allclose(np.degrees(c.design[last, k.edges]), 90.0, atol=1e-9)
    # ~3 deg springback on 90 deg: programmed ~93 deg on every hinge of the crease
    np.testing.assert_allclose(np.degrees(c.programmed[last, k.edges]), 93.1, atol=0.15)


def test_tight_radius_and_unreachable_angles_are_refused(reflect_seq):
    m = get_material("5052-H32")
    with pytest.raises(BendRadiusError, match="crease 0"):
        compensate_sequence(reflect_seq, sheet_spec(m, 2 * MM, inside_radius=1 * MM))
    thin = sheet_spec(replace(m, flow_stress_rule="yield"), 1 * MM, "grooved", ligament=0.1 * MM)
    with pytest.raises(SpringbackError, match="crease"):
        compensate_sequence(reflect_seq, thin)


def test_foreign_fold_without_fabkit_tags(straight_seq):
    # the same sequence as another tool would write it: no edges_fabkit:kind / crease tags
    bare = replace(straight_seq, edges_data={}, faces_data={}, file_data={})
    assert isinstance(bare, FoldModel)
    spec = sheet_spec(get_material("3003-H14"), 1 * MM)
    c = compensate_sequence(bare, spec)
    (k,) = panel_creases(bare)
    assert len(k.edges) == 3 and k.length == pytest.approx(0.75)
    assert np.all(np.abs(c.programmed[-1, k.edges]) > 90 * DEG)


def test_foreign_fold_with_its_own_edge_order(straight_seq):
    # another tool's FOLD: edges in a different order, vertices listed hi-lo, no fabkit tags, no
    # per-frame angles (the angles are measured from the coordinates)
    rng = np.random.default_rng(3)
    E = straight_seq.n_edges
    perm = rng.permutation(E)
    ev = np.asarray(straight_seq.edges_vertices)[perm][:, ::-1]
    frames = tuple(replace(f, edges_fold_angle=None, data={}) for f in straight_seq.frames)
    bare = replace(straight_seq, edges_vertices=ev, edges_assignment=np.asarray(straight_seq.edges_assignment)[perm],
                   edges_fold_angle=np.asarray(straight_seq.edges_fold_angle)[perm], edges_data={}, faces_data={},
                   file_data={}, frames=frames)
    spec = sheet_spec(get_material("5052-H32"), 1.6 * MM, inside_radius=1.6 * MM)
    c = compensate_sequence(bare, spec)
    (k,) = panel_creases(bare)
    np.testing.assert_allclose(np.degrees(c.design[-1, k.edges]), 90.0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(c.programmed[-1, k.edges]), 93.1, atol=0.15)
    ref = compensate_sequence(straight_seq, spec)
    np.testing.assert_allclose(np.asarray(c.model.frames[-1].vertices_coords),
                               np.asarray(ref.model.frames[-1].vertices_coords), atol=1e-9)


def test_a_foreign_sequence_keeps_its_own_panel_frame(straight_seq):
    # the same fold, with the whole sequence moved (another tool's frame): the compensated states
    # stay in that frame (the face that does not fold stays where the design has it)
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec([0.3, -0.2, 1.1])
    moved = tuple(replace(f, vertices_coords=R.apply(np.array(f.vertices_coords)) + [0.5, -0.2, 0.1],
                          edges_fold_angle=None) for f in straight_seq.frames)
    seq = replace(straight_seq, frames=moved, file_data={})
    spec = sheet_spec(get_material("5052-H32"), 1.6 * MM, inside_radius=1.6 * MM)
    c = compensate_sequence(seq, spec)
    ref = compensate_sequence(straight_seq, spec)
    want = R.apply(np.array(ref.model.frames[-1].vertices_coords)) + [0.5, -0.2, 0.1]
    np.testing.assert_allclose(np.asarray(c.model.frames[-1].vertices_coords), want, atol=1e-9)


def test_crease_rows_without_row_tags_are_the_structures(reflect_seq):
    """Without `edges_fabkit:crease` the rows come from `fabkit.structure` (the strips between the
    crease edges): the same rows refold wrote, also with another edge order."""
    tagged = panel_creases(reflect_seq)
    kind = np.asarray(reflect_seq.edges_data["kind"])
    E = reflect_seq.n_edges
    perm = np.random.default_rng(5).permutation(E)
    for model, edge_of in ((replace(reflect_seq, edges_data={"kind": kind}), np.arange(E)),
                           (replace(reflect_seq, edges_vertices=np.asarray(reflect_seq.edges_vertices)[perm][:, ::-1],
                                    edges_assignment=np.asarray(reflect_seq.edges_assignment)[perm],
                                    edges_fold_angle=np.asarray(reflect_seq.edges_fold_angle)[perm],
                                    edges_data={"kind": kind[perm]},
                                    frames=tuple(replace(f, edges_fold_angle=None, data={})
                                                 for f in reflect_seq.frames)), perm)):
        bare = panel_creases(model)
        assert [k.name for k in bare] == [k.name for k in tagged] == ["crease 0", "crease 1"]
        for k, t in zip(bare, tagged):
            assert sorted(edge_of[k.edges].tolist()) == sorted(t.edges.tolist())
            assert k.length == pytest.approx(t.length, rel=1e-12) and k.kappa_g == pytest.approx(t.kappa_g, rel=1e-9)
