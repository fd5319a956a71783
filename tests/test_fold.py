"""FoldModel, FOLD 1.2 reading/writing, and reading our files with the reference JS implementation."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from fabkit.errors import InputError
from fabkit.fold import FoldFrame, FoldModel, default_assignment, validate_fold_model
from fabkit.io.fold import fold_to_json, load_fold, save_fold
from fabkit.measures import dihedral_angles
from io_meshes import MIXED_F, folded_coords, grid, mixed_mesh

DATA = Path(__file__).parent / "data" / "fold"
FOLD_JS_VERSION = "0.12.0"  # npm view fold version (2026-11)


def folded_model(n_frames: int = 3) -> FoldModel:
    """Mixed panel folded along x = 0.1 in n_frames steps up to 90 degrees (valley)."""
    mesh = mixed_mesh()
    target = np.radians(90.0)
    base = FoldModel.from_mesh(mesh)
    crease = np.zeros(mesh.n_edges, bool)
    crease[[3, 9]] = True  # edges (1, 4) and (4, 7): the hinge line x = 0.1
    assignment = np.where(crease, "V", base.edges_assignment)
    frames = []
    for k in range(1, n_frames + 1):
        angle = target * k / n_frames
        V = folded_coords(mesh, angle)
        frames.append(FoldFrame(V, np.where(crease, angle, 0.0)))
    return FoldModel.from_mesh(mesh, assignment, np.where(crease, target, 0.0), frames=frames,
                               title="mixed panel", file_data={"panel": "P1", "thickness_m": 0.002})


# ---- FoldModel -----------------------------------------------------------------------------------
def test_from_mesh_uses_mesh_edge_order_and_data():
    mesh = mixed_mesh()
    model = FoldModel.from_mesh(mesh)
    assert np.array_equal(model.edges_vertices, mesh.edges)
    assert [list(f) for f in model.faces_vertices] == MIXED_F
    assert set(model.faces_data) == {"strip", "column", "middle"}
    assert np.array_equal(model.vertices_data["pinned"], mesh.vertex_data["pinned"])
    assert np.array_equal(model.mesh_edge_index, np.arange(mesh.n_edges))
    # boundary edges B; the edges whose faces have different strips are unassigned creases U
    ef = mesh.edge_faces
    boundary = np.any(ef < 0, axis=1)
    assert np.all(model.edges_assignment[boundary] == "B")
    strip = mesh.face_data["strip"]
    crease = ~boundary & (strip[ef[:, 0]] != strip[ef[:, 1]])
    assert np.all(model.edges_assignment[crease] == "U")
    assert np.all(model.edges_assignment[~boundary & ~crease] == "F")
    assert model.attributes == ("2D",)


def test_default_assignment_follows_fold_angle_sign():
    mesh = grid(3, 1)
    angle = np.zeros(mesh.n_edges)
    inner = mesh.topology.interior_edges
    angle[inner[0]], angle[inner[1]] = 0.3, -0.2
    a = default_assignment(mesh, angle)
    assert a[inner[0]] == "V" and a[inner[1]] == "M"
    assert "".join(sorted(set(a[mesh.topology.boundary_edge_mask]))) == "B"


def test_mesh_and_frame_mesh_round_trip():
    model = folded_model(3)
    key = model.mesh()
    assert key.faces_list() == MIXED_F
    assert np.array_equal(key.vertices, mixed_mesh().vertices)
    assert key.face_data["middle"].tolist() == [1, 1, 0, 0, 0]
    last = model.frame_mesh(-1)
    assert last.topology is key.topology or last.faces_list() == MIXED_F
    d = dihedral_angles(last)
    hinge = model.edges_assignment == "V"
    np.testing.assert_allclose(d[hinge], np.pi / 2, atol=1e-12)  # valley +90 degrees, measured
    np.testing.assert_allclose(model.frame_fold_angle(0)[hinge], np.pi / 6)
    with pytest.raises(IndexError):
        model.frame_mesh(3)


def test_model_is_read_only():
    model = folded_model(1)
    with pytest.raises(Exception):
        model.unit = "m"
    with pytest.raises(ValueError):
        model.vertices_coords[0, 0] = 1.0
    with pytest.raises(ValueError):
        model.frames[0].vertices_coords[0, 0] = 1.0


@pytest.mark.parametrize("change, needle", [
    (lambda m: dict(edges_assignment=np.array(list("BBBVBBBBBXBBBB"))), "assignment 'X'"),
    (lambda m: dict(edges_assignment=m.edges_assignment[:-1]), "edges_assignment has 13 entries for 14 edges"),
    (lambda m: dict(edges_fold_angle=np.where(m.edges_assignment == "V", -0.5, 0.0)), "is a valley (V)"),
    (lambda m: dict(edges_assignment=np.where(m.edges_assignment == "V", "M", m.edges_assignment)), "is a mountain"),
    (lambda m: dict(edges_fold_angle=np.where(m.edges_assignment == "V", 3.2, 0.0)), "outside [-180, 180]"),
    (lambda m: dict(edges_vertices=np.where(m.edges_vertices == 9, 10, m.edges_vertices)), "refers to vertex"),
    (lambda m: dict(faces_vertices=[[0, 1, 4, 3], [1, 2, 9, 5, 4], [3, 4, 7], [3, 7, 6], [4, 5, 8]]),
     "not in edges_vertices"),
    (lambda m: dict(faces_vertices=[[0, 1, 4, 3], [1, 2, 9, 5, 4], [3, 4, 7], [3, 7, 7], [4, 5, 8, 7]]),
     "repeats vertex 7"),
    (lambda m: dict(faces_vertices=[[0, 3, 4, 1], [1, 2, 9, 5, 4], [3, 4, 7], [3, 7, 6], [4, 5, 8, 7]]),
     "face 0 is clockwise"),
    (lambda m: dict(vertices_coords=np.where(np.arange(30).reshape(10, 3) == 4, np.nan, m.vertices_coords)),
     "vertex 1 has a non-finite"),
    (lambda m: dict(faces_data={"strip": np.array([0, 1])}), "faces_fabkit:strip has 2 entries for 5 faces"),
    (lambda m: dict(frames=(FoldFrame(np.zeros((9, 3))),)), "frame 1: vertices_coords has shape (9, 3)"),
    (lambda m: dict(frames=(FoldFrame(m.vertices_coords, np.full(14, np.radians(-10.0))),)), "frame 1: edge 3"),
])
def test_validate_fold_model_rejects(change, needle):
    model = folded_model(1)
    import dataclasses

    bad = dataclasses.replace(model, **change(model))
    with pytest.raises(InputError) as err:
        validate_fold_model(bad, source="x.fold")
    assert needle in str(err.value)
    assert str(err.value).startswith("x.fold: ")


def test_validate_rejects_edge_on_three_faces():
    # three triangles on edge (0, 1): a fan that is not a surface
    V = [[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]]
    model = FoldModel(V, [[0, 1, 2], [1, 0, 3], [0, 1, 4]],
                      [[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [1, 4], [0, 4]], list("FBBBBBB"), np.zeros(7),
                      classes=("foldedForm",))
    with pytest.raises(InputError, match=r"edge 0 \(F\) borders 3 faces \[0, 1, 2\]"):
        validate_fold_model(model)


# ---- writing -------------------------------------------------------------------------------------
def test_written_layout(tmp_path):
    model = folded_model(2)
    path = tmp_path / "panel.fold"
    save_fold(model, path)
    d = json.loads(path.read_text())
    assert d["file_spec"] == 1.2 and d["file_creator"] == "fabkit"
    assert d["file_classes"] == ["animation"]
    assert d["frame_classes"] == ["creasePattern"] and d["frame_unit"] == "mm"
    assert d["file_fabkit:panel"] == "P1"
    assert d["faces_fabkit:strip"] == [0, 1, 0, 0, 1]
    assert d["vertices_fabkit:pinned"][:2] == [True, False]
    assert np.allclose(np.array(d["vertices_coords"]), model.vertices_coords * 1000, rtol=0, atol=1e-12)
    assert len(d["file_frames"]) == 2
    for f in d["file_frames"]:
        assert f["frame_parent"] == 0 and f["frame_inherit"] is True
        assert f["frame_classes"] == ["foldedForm"] and f["frame_attributes"] == ["3D"]
        assert set(f) == {"frame_parent", "frame_inherit", "frame_classes", "frame_attributes",
                          "vertices_coords", "edges_foldAngle"}
    hinge = [i for i, a in enumerate(d["edges_assignment"]) if a == "V"]
    assert [d["edges_foldAngle"][i] for i in hinge] == [90.0, 90.0]
    assert [d["file_frames"][0]["edges_foldAngle"][i] for i in hinge] == [45.0, 45.0]


def test_null_fold_angle_written_as_null(tmp_path):
    mesh = grid(2, 1)
    angle = np.zeros(mesh.n_edges)
    angle[mesh.topology.boundary_edge_mask] = np.nan
    model = FoldModel.from_mesh(mesh, edges_fold_angle=angle)
    d = fold_to_json(model)
    assert d["edges_foldAngle"].count(None) == int(mesh.topology.boundary_edge_mask.sum())
    save_fold(model, tmp_path / "n.fold")
    back = load_fold(tmp_path / "n.fold")
    assert np.array_equal(np.isnan(back.edges_fold_angle), np.isnan(angle))


def test_round_trip_is_exact(tmp_path, rng):
    mesh = mixed_mesh(scale=1.2345, jitter=0.01)
    frames = [FoldFrame(folded_coords(mesh, a) + rng.normal(scale=1e-3, size=(10, 3)), None)
              for a in (0.1, 0.7)]
    angle = np.zeros(mesh.n_edges)
    angle[[3, 9]] = rng.uniform(0, np.pi, 2)
    model = FoldModel.from_mesh(mesh, edges_fold_angle=angle, frames=frames,
                                edges_data={"ruling": np.arange(mesh.n_edges) % 3 == 0})
    path = tmp_path / "rt.fold"
    save_fold(model, path)
    back = load_fold(path)
    assert np.array_equal(back.vertices_coords, model.vertices_coords)  # bitwise, not just close
    assert back.faces_vertices == model.faces_vertices
    assert np.array_equal(back.edges_vertices, model.edges_vertices)
    assert back.edges_assignment.tolist() == model.edges_assignment.tolist()
    assert np.array_equal(back.edges_fold_angle, model.edges_fold_angle)
    for a, b in zip(back.frames, model.frames):
        assert np.array_equal(a.vertices_coords, b.vertices_coords)
        assert a.edges_fold_angle is None
    for kind in ("faces_data", "vertices_data", "edges_data"):
        ours, theirs = getattr(model, kind), getattr(back, kind)
        assert set(ours) == set(theirs)
        for k in ours:
            assert np.array_equal(ours[k], theirs[k]) and ours[k].dtype.kind == theirs[k].dtype.kind
    assert back.unit == "mm" and back.notes == ()
    # writing what we read gives the same bytes
    save_fold(back, tmp_path / "rt2.fold")
    assert (tmp_path / "rt2.fold").read_bytes() == path.read_bytes()


def test_unit_and_angle_conversion_exact_on_many_random_values(rng):
    from fabkit.io.fold_numbers import degrees_to_radians, metres_to_mm_text, Num, radians_to_degrees_text, to_si

    V = rng.uniform(-3, 3, size=3000) * 10.0 ** rng.integers(-6, 2, size=3000)
    texts = [metres_to_mm_text(x) for x in V]
    back = np.array([to_si(Num(t) if "." in t or "e" in t else int(t), "mm") for t in texts])
    assert np.array_equal(back, V)
    # the same through the decimal path (exponent texts) and the text of a JSON integer
    assert to_si(Num("1.5e-2"), "mm") == 1.5e-5 and to_si(1500, "mm") == 1.5
    assert to_si(Num("2.54"), "cm") == 0.0254 and to_si(Num("0.1"), "m") == 0.1
    np.testing.assert_allclose(np.array([float(t) for t in texts]), V * 1000, rtol=1e-15)
    A = np.concatenate([rng.uniform(-np.pi, np.pi, 3000), [np.pi, -np.pi, np.pi / 2, 0.0]])
    deg = [radians_to_degrees_text(a) for a in A]
    assert np.array_equal(np.array([degrees_to_radians(Num(t)) for t in deg]), A)
    assert deg[-4:] == ["180.0", "-180.0", "90.0", "0"]
    assert max(len(t) for t in deg) <= 24
    assert to_si(1, "in") == 0.0254 and to_si(72, "pt") == 0.0254 and to_si(Num("0.5"), "um") == 5e-7


# ---- reading public-style shapes (our own look-alike fixtures) -----------------------------------
def test_reads_3d_folded_form_without_spec():
    m = load_fold(DATA / "simple-3d.fold")
    assert (m.n_vertices, m.n_edges, m.n_faces) == (6, 9, 4)
    assert m.unit == "unit" and any("no file_spec" in n for n in m.notes)
    assert any("taken as metres" in n for n in m.notes)
    # no edges_foldAngle: unknown (NaN) on M/V, 0 on B
    assert np.all(np.isnan(m.edges_fold_angle[:3])) and np.all(m.edges_fold_angle[3:] == 0)
    assert m.mesh().n_faces == 4


def test_reads_spec_1_1_crease_pattern_with_old_angle_name():
    m = load_fold(DATA / "diagonal-cp-1.1.fold")
    assert m.classes == ("creasePattern",) and m.title == "one diagonal"
    assert np.degrees(m.edges_fold_angle).tolist() == [0, 0, 0, 0, 180]
    assert any("edges_foldAngles" in n for n in m.notes)
    assert m.vertices_coords.shape == (4, 3) and np.all(m.vertices_coords[:, 2] == 0)
    assert m.file_data["myeditor:page"]["xMax"] == 2  # foreign namespaced keys are kept


def test_reads_xz_plane_pattern_and_rotates_it():
    m = load_fold(DATA / "pleat-xz.fold")
    assert m.classes == ("foldedForm",) and m.attributes == ("3D",)
    assert any("XZ plane" in n for n in m.notes)
    assert np.all(m.vertices_coords[:, 2] == 0.0)
    mesh = m.mesh()
    np.testing.assert_array_equal(mesh.face_normals, np.tile([0.0, 0.0, 1.0], (4, 1)))
    assert m.faces_vertices[0] == (0, 1, 3, 2)  # quads kept
    assert np.isnan(m.edges_fold_angle[0]) and m.edges_assignment[0] == "B"
    assert np.degrees(m.edges_fold_angle[1:4]).tolist() == [-180, 180, -180]
    # lengths are kept by the rotation (unit 'unit' is read as metres)
    np.testing.assert_allclose(np.sort(mesh.edge_lengths), np.sort([0.5] * 5 + [0.25] * 8))


def test_reads_frames_with_chained_inheritance(tmp_path):
    d = fold_to_json(folded_model(2))
    d["file_frames"].append({"frame_parent": 2, "frame_inherit": True, "frame_classes": ["foldedForm"],
                             "frame_unit": "cm"})
    d["file_frames"].append({"frame_parent": 1, "frame_inherit": True,
                             "vertices_coords": [[c / 10 for c in v] for v in d["vertices_coords"]],
                             "frame_unit": "cm"})
    p = tmp_path / "chain.fold"
    p.write_text(json.dumps(d))
    m = load_fold(p)
    assert m.n_frames == 4
    np.testing.assert_array_equal(m.frames[2].vertices_coords, m.frames[1].vertices_coords)
    np.testing.assert_array_equal(m.frame_fold_angle(2), m.frame_fold_angle(1))
    np.testing.assert_allclose(m.frames[3].vertices_coords, m.vertices_coords, rtol=1e-15)
    np.testing.assert_array_equal(m.frame_fold_angle(3), m.frame_fold_angle(0))


# ---- Origami Simulator importer and the reference self-validation --------------------------------
def test_origami_simulator_required_fields_and_self_validation(tmp_path):
    path = tmp_path / "panel.fold"
    save_fold(folded_model(3), path)
    d = json.loads(path.read_text())
    # the four fields Origami Simulator's importer requires, with the right shapes
    for key in ("vertices_coords", "edges_vertices", "edges_assignment", "faces_vertices"):
        assert key in d and isinstance(d[key], list) and d[key]
    n, E, F = len(d["vertices_coords"]), len(d["edges_vertices"]), len(d["faces_vertices"])
    assert all(len(v) in (2, 3) for v in d["vertices_coords"])
    # reference §1.3: parallel arrays, indices in range
    assert len(d["edges_assignment"]) == len(d["edges_foldAngle"]) == E
    assert all(0 <= i < n for e in d["edges_vertices"] for i in e)
    assert all(0 <= i < n for f in d["faces_vertices"] for i in f)
    for k, v in d.items():
        if k.startswith("faces_fabkit:"):
            assert len(v) == F
        if k.startswith("vertices_fabkit:"):
            assert len(v) == n
    # counter-clockwise faces in the 2D key frame
    V = np.array(d["vertices_coords"])
    for f in d["faces_vertices"]:
        x, y = V[f, 0], V[f, 1]
        assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0
    # fold-angle sign matches M/V; angles within [-180, 180]
    for frame in [d] + d["file_frames"]:
        for a, ang in zip(d["edges_assignment"], frame["edges_foldAngle"]):
            assert ang is None or -180 <= ang <= 180
            assert not (a == "V" and ang is not None and ang < 0)
            assert not (a == "M" and ang is not None and ang > 0)
    # every non-B edge borders at most 2 faces; B edges exactly one
    count = {}
    for f in d["faces_vertices"]:
        for a, b in zip(f, f[1:] + f[:1]):
            count[(min(a, b), max(a, b))] = count.get((min(a, b), max(a, b)), 0) + 1
    for (a, b), asg in zip(d["edges_vertices"], d["edges_assignment"]):
        c = count[(min(a, b), max(a, b))]
        assert c == 1 if asg == "B" else c <= 2
    assert d["file_spec"] == 1.2 and d["file_creator"] and d["frame_unit"] == "mm"


# ---- the reference JavaScript implementation reads our files -------------------------------------
def _fold_js_package() -> Path:
    """Install npm `fold` once into a cache directory outside the source tree; skip if impossible."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if not node or not npm:
        pytest.skip("node/npm not installed: cannot run the reference FOLD implementation")
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "fabkit-tests" / f"npm-fold-{FOLD_JS_VERSION}"
    pkg = cache / "node_modules" / "fold"
    if (pkg / "package.json").exists():
        return pkg
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix="npm-fold-", dir=cache.parent))
    try:
        r = subprocess.run([npm, "install", "--no-save", "--no-audit", "--no-fund", "--prefix", str(tmp),
                            f"fold@{FOLD_JS_VERSION}"], capture_output=True, text=True, timeout=180)
    except subprocess.TimeoutExpired:
        shutil.rmtree(tmp, ignore_errors=True)
        pytest.skip("npm install fold timed out (registry unreachable?)")
    if r.returncode != 0:
        shutil.rmtree(tmp, ignore_errors=True)
        pytest.skip(f"npm install fold@{FOLD_JS_VERSION} failed (registry unreachable?): "
                    f"{r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
    try:
        os.replace(tmp, cache)
    except OSError:  # another run installed it meanwhile
        shutil.rmtree(tmp, ignore_errors=True)
    return pkg


def _read_with_js(path: Path) -> dict:
    pkg = _fold_js_package()
    r = subprocess.run(["node", str(DATA / "read_with_fold_js.js"), str(pkg), str(path)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def _cyclic(face) -> tuple:
    k = int(np.argmin(face))
    return tuple(face[k:]) + tuple(face[:k])


def test_reference_js_reads_our_fold(tmp_path):
    model = folded_model(3)
    path = tmp_path / "panel.fold"
    save_fold(model, path)
    js = _read_with_js(path)
    assert (js["numVertices"], js["numEdges"], js["numFaces"]) == (model.n_vertices, model.n_edges, model.n_faces)
    assert js["spec"] == 1.2 and js["creator"] == "fabkit" and js["unit"] == "mm"
    assert js["fileClasses"] == ["animation"] and js["frameClasses"] == ["creasePattern"]
    counts = {a: int(np.sum(model.edges_assignment == a)) for a in "BMVFJUC"}
    assert js["assigned"] == counts
    assert js["faceOrientation"] == [1] * model.n_faces  # counter-clockwise, per the JS geometry
    assert js["missingFaceSides"] == 0
    # the JS library finds exactly our faces in the planar crease pattern (quads and the pentagon kept)
    assert sorted(_cyclic(f) for f in js["recoveredFaces"]) == sorted(_cyclic(f) for f in model.faces_vertices)
    assert "faces_fabkit:strip" in js["facesKeys"] and "vertices_fabkit:pinned" in js["verticesKeys"]
    # JS reads doubles of millimetres: dividing by 1000 there may differ by one ulp from our exact read
    np.testing.assert_allclose(np.array(js["coords"]) / 1000.0, model.vertices_coords, rtol=0, atol=1e-15)
    assert len(js["frames"]) == 3
    for frame_js, frame in zip(js["frames"], model.frames):
        assert frame_js["parent"] == 0 and frame_js["inherit"] is True
        assert frame_js["classes"] == ["foldedForm"] and frame_js["attributes"] == ["3D"]
        np.testing.assert_allclose(np.array(frame_js["coords"]) / 1000.0, frame.vertices_coords, rtol=0, atol=1e-15)
        np.testing.assert_allclose(np.radians(np.array(frame_js["foldAngle"], dtype=float)),
                                   frame.edges_fold_angle, rtol=0, atol=1e-15)


def test_reference_js_reads_rotated_pleat(tmp_path):
    m = load_fold(DATA / "pleat-xz.fold")
    path = tmp_path / "pleat.fold"
    save_fold(m, path)
    js = _read_with_js(path)
    assert js["faceOrientation"] == [1, 1, 1, 1]
    assert js["foldAngle"][0] is None and js["foldAngle"][1:4] == [-180, 180, -180]
    assert sorted(_cyclic(f) for f in js["recoveredFaces"]) == sorted(_cyclic(f) for f in m.faces_vertices)


# ---- property tests of the exact conversions -----------------------------------------------------
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=400, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_any_double_survives_the_mm_text(x):
    from fabkit.io.fold_numbers import metres_to_mm_text, Num, to_si

    text = metres_to_mm_text(x)
    value = json.loads(text, parse_float=Num)  # what the reader sees
    back = to_si(value, "mm")
    assert back == x and (x != 0 or np.signbit(back) == np.signbit(x) or text in ("0", "-0"))


@settings(max_examples=400, deadline=None)
@given(st.floats(min_value=-np.pi, max_value=np.pi))
def test_any_angle_survives_the_degree_text(a):
    from fabkit.io.fold_numbers import degrees_to_radians, Num, radians_to_degrees_text

    text = radians_to_degrees_text(a)
    value = json.loads(text, parse_float=Num)
    assert degrees_to_radians(value) == a
    assert abs(float(text)) <= 180.0


def test_angle_just_beyond_pi_is_refused_before_writing(tmp_path):
    mesh = grid(2, 1)
    angle = np.zeros(mesh.n_edges)
    angle[mesh.topology.interior_edges[0]] = np.nextafter(np.pi, 4.0)
    with pytest.raises(InputError, match="outside"):
        FoldModel.from_mesh(mesh, edges_fold_angle=angle)
    angle[mesh.topology.interior_edges[0]] = np.pi  # exactly 180 degrees is fine and reads back as pi
    save_fold(FoldModel.from_mesh(mesh, edges_fold_angle=angle), tmp_path / "pi.fold")
    assert load_fold(tmp_path / "pi.fold").edges_fold_angle.max() == np.pi


def test_project_data_2d_with_nan_and_strings_round_trip(tmp_path):
    mesh = grid(2, 1)
    uv = np.arange(12, dtype=float).reshape(6, 2) / 7
    uv[2, 1] = np.nan
    model = FoldModel.from_mesh(mesh.with_data(vertex_data={"uv": uv}, face_data={"name": np.array(["a", "b"])}))
    save_fold(model, tmp_path / "d.fold")
    back = load_fold(tmp_path / "d.fold")
    assert np.array_equal(back.vertices_data["uv"], uv, equal_nan=True)
    assert back.faces_data["name"].tolist() == ["a", "b"]
    d = json.loads((tmp_path / "d.fold").read_text())
    assert d["vertices_fabkit:uv"][2] == [4 / 7, None]
    d["faces_fabkit:bad"] = [1, "x"]
    (tmp_path / "bad.fold").write_text(json.dumps(d))
    with pytest.raises(InputError, match="faces_fabkit:bad mixes number, str"):
        load_fold(tmp_path / "bad.fold")
    d["faces_fabkit:bad"] = [[1, 2], [3]]
    (tmp_path / "bad.fold").write_text(json.dumps(d))
    with pytest.raises(InputError, match="faces_fabkit:bad is not a regular array"):
        load_fold(tmp_path / "bad.fold")


def test_unused_vertex_in_a_fold_file_warns_with_the_file_name(tmp_path):
    d = fold_to_json(FoldModel.from_mesh(grid(1, 1)))
    d["vertices_coords"].append([500.0, 500.0, 0.0])
    p = tmp_path / "u.fold"
    p.write_text(json.dumps(d))
    with pytest.warns(UserWarning, match=f"{p}: 1 unused vertices"):
        m = load_fold(p)
    assert any("unused" in n for n in m.notes) and m.n_vertices == 5
