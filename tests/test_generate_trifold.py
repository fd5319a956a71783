"""The Fig. 3 tri-fold preset: a clean three-strip curved-crease panel, close to developable, tags kept."""
import numpy as np
import pytest

from fabkit import measures
from fabkit.errors import InputError
from fabkit.generate import trifold_panel


def creases(mesh):
    st = mesh.face_data["strip"]
    ef = mesh.edge_faces
    inner = np.all(ef >= 0, axis=1)
    a, b = st[np.maximum(ef[:, 0], 0)], st[np.maximum(ef[:, 1], 0)]
    return [np.flatnonzero(inner & (a != b) & (np.minimum(a, b) == c)) for c in (0, 1)]


def polyline(mesh, edge_ids):
    """Vertices of a set of edges forming one open polyline, in order (fails otherwise)."""
    E = mesh.edges[edge_ids]
    deg = np.bincount(E.ravel(), minlength=mesh.n_vertices)
    assert np.all(deg <= 2) and np.sum(deg == 1) == 2
    start = int(np.flatnonzero(deg == 1)[0])
    order, seen = [start], {start}
    for _ in range(len(E)):
        nxt = [int(w) for a, b in E for v, w in ((a, b), (b, a)) if v == order[-1] and w not in seen]
        if not nxt:
            break
        order.append(nxt[0])
        seen.add(nxt[0])
    assert len(order) == len(E) + 1
    return np.array(order)


PARAMS = [dict(), dict(resolution=6), dict(height=0.5, resolution=32), dict(length=1.0, depth=0.5, bevel=0.3, extrude=0.08)]


@pytest.mark.parametrize("params", PARAMS)
def test_clean_three_strip_panel(params):
    m = trifold_panel(**params)
    C = 2 ** int(np.ceil(np.log2(params.get("resolution", 16))))
    # manifold, consistently oriented (PolyMesh checks both), open, one boundary loop, all quads
    assert len(m.boundary_loops) == 1 and np.all(m.face_sizes == 4)
    assert (m.n_faces, m.n_vertices) == (3 * C, 4 * (C + 1))
    st, col, mid = m.face_data["strip"], m.face_data["column"], m.face_data["middle"]
    assert np.bincount(st).tolist() == [C, C, C]
    for s in range(3):
        assert sorted(col[st == s]) == list(range(C))
    # the middle row: one face per strip, all in column C // 2, ordered by strip along +y
    middle = np.flatnonzero(mid)
    assert len(middle) == 3 and sorted(st[middle]) == [0, 1, 2] and np.all(col[middle] == C // 2)
    y = {int(st[f]): m.face_centroids[f, 1] for f in middle}
    assert y[0] < y[1] < y[2]
    # panel frame: front faces +z, columns run along +x
    assert np.all(m.face_normals[:, 2] > 0.5)
    cx = [m.face_centroids[(st == 1) & (col == c), 0][0] for c in range(C)]
    assert np.all(np.diff(cx) > 0)
    # two creases, each a simple polyline from boundary to boundary with one edge per column
    for c in creases(m):
        assert len(c) == C
        line = polyline(m, c)
        assert m.boundary_vertex_mask[line[[0, -1]]].all() and not m.boundary_vertex_mask[line[1:-1]].any()


@pytest.mark.parametrize("params", PARAMS)
def test_close_to_developable_with_clear_curved_creases(params):
    m = trifold_panel(**params)
    # a good relax input: faces planar (measured: round-off), angle defect small but not zero
    assert measures.face_planarity(m).max() <= 1e-9
    defect = np.abs(measures.interior_angle_defect(m))
    assert 1e-4 < defect.max() < 0.05
    d = measures.dihedral_angles(m)
    for c in creases(m):
        # clearly folded, one sign along the crease (mountain: the box's outside is the front)
        assert np.all(d[c] < -np.radians(20))
        line = polyline(m, c)
        P = m.vertices[line]
        chord = P[-1] - P[0]
        off = (P - P[0]) - np.outer((P - P[0]) @ chord / (chord @ chord), chord)
        sagitta = np.linalg.norm(off, axis=1).max() / np.linalg.norm(chord)
        assert sagitta > 0.02  # curved
        # and planar: a planar arc (paper §3.1), the sharp-crease B-spline of a planar hole border
        sv = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
        assert sv[2] <= 1e-12 * sv[0]
    # the outer strips lie flat (in the box's face planes)
    for s in (0, 2):
        P = m.vertices[np.unique(m.topology.face_array[m.face_data["strip"] == s])]
        sv = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
        assert sv[2] <= 1e-12 * sv[0]


@pytest.mark.parametrize("rows", [2, 4])
def test_more_rows_per_strip(rows):
    m = trifold_panel(resolution=8, rows=rows)
    assert (m.n_faces, m.n_vertices) == (3 * 8 * rows, (8 + 1) * (3 * rows + 1))
    assert len(m.boundary_loops) == 1 and np.all(m.face_sizes == 4)
    st, col, mid = m.face_data["strip"], m.face_data["column"], m.face_data["middle"]
    assert np.bincount(st).tolist() == [8 * rows] * 3
    middle = np.flatnonzero(mid)
    assert sorted(st[middle]) == [0, 1, 2] and np.all(col[middle] == 4)
    # the creases are the same curves as in the one-row panel (compared by their own distances,
    # since the panel frame depends on all faces)
    one = trifold_panel(resolution=8)
    for a, b in zip(creases(m), creases(one)):
        pa, pb = m.vertices[polyline(m, a)], one.vertices[polyline(one, b)]
        da = np.linalg.norm(pa[:, None] - pa[None], axis=2)
        db = np.linalg.norm(pb[:, None] - pb[None], axis=2)
        assert np.allclose(da, db, atol=1e-12) or np.allclose(da, db[::-1, ::-1], atol=1e-12)
    assert np.abs(measures.interior_angle_defect(m)).max() < 0.05
    assert measures.face_planarity(m).max() < 0.01  # the middle strip's inner lines are Catmull–Clark lines


def test_height_changes_the_two_fold_angles():
    m = trifold_panel(height=0.5)
    d = measures.dihedral_angles(m)
    c0, c1 = creases(m)
    assert abs(np.median(d[c0]) - np.median(d[c1])) > np.radians(10)


@pytest.mark.parametrize("kwargs, word", [
    (dict(length=-1.0), "length"),
    (dict(depth=0.0), "depth"),
    (dict(height=float("inf")), "height"),
    (dict(bevel=0.5), "bevel"),
    (dict(bevel=0.0), "bevel"),
    (dict(extrude=0.0), "extrude"),
    (dict(extrude=0.6), "extrude must be smaller"),
    (dict(resolution=1), "resolution"),
    (dict(resolution=1000), "resolution"),
    (dict(resolution=2.5), "resolution"),
    (dict(rows=3), "rows"),
    (dict(rows=32, resolution=16), "rows"),
    (dict(rows=0), "rows"),
])
def test_bad_parameters(kwargs, word):
    with pytest.raises(InputError, match=word):
        trifold_panel(**kwargs)


def test_tags_survive_obj_and_fold_round_trips(tmp_path):
    from fabkit.fold import FoldModel
    from fabkit.io.fold import load_fold, save_fold
    from fabkit.io.obj import load_obj, save_obj

    m = trifold_panel(resolution=8)
    save_obj(m, tmp_path / "t.obj")
    back = load_obj(tmp_path / "t.obj")
    assert np.array_equal(back.vertices, m.vertices) and back.faces_list() == m.faces_list()
    for k in ("strip", "column", "middle"):
        assert np.array_equal(back.face_data[k], m.face_data[k])
    save_fold(FoldModel.from_mesh(m), tmp_path / "t.fold")
    fold = load_fold(tmp_path / "t.fold")
    fm = fold.mesh()
    assert fm.faces_list() == m.faces_list()
    assert np.allclose(fm.vertices, m.vertices, atol=1e-12)
    for k in ("strip", "column", "middle"):
        assert np.array_equal(fm.face_data[k], m.face_data[k])
    # crease edges are the edges between strips
    crease = np.concatenate(creases(m))
    assert set(np.flatnonzero(np.isin(fold.edges_assignment, ["M", "V", "U"]))) == set(crease)


def test_cli_trifold_written_file(tmp_path):
    from fabkit.cli import main
    from fabkit.io.obj import load_obj

    out = tmp_path / "t.obj"
    assert main(["generate", "trifold", "-o", str(out), "-q"]) == 0
    m = load_obj(out)
    assert len(m.boundary_loops) == 1 and np.all(m.face_sizes == 4)  # open, quad-dominant (all quads)
    assert sorted(np.unique(m.face_data["strip"])) == [0, 1, 2]
    assert m.face_data["middle"].sum() == 3
    assert main(["generate", "trifold", "-o", str(tmp_path / "s.obj"), "--resolution", "6", "-q"]) == 0
    assert load_obj(tmp_path / "s.obj").n_faces == 24
