"""Cut files: creases and their sense, DXF read back with ezdxf, SVG parsed back, all in millimetres."""
import xml.etree.ElementTree as ET

import ezdxf
import numpy as np
import pytest

from fabkit.cutfiles import chain_edges, crease_assignment, cut_pattern, write_dxf, write_svg
from fabkit.cutfiles.svg import MARGIN_MM
from fabkit.unfold import develop
from unfold_shapes import flat_grid, folded_grid

SVG = "{http://www.w3.org/2000/svg}"


def crease_edges(mesh, u0):
    """Edges on the line u = u0 of a folded grid (in the flat grid's coordinates)."""
    _, uv = flat_grid(8, 5)
    on = np.abs(uv[:, 0] - u0) < 1e-12
    return np.flatnonzero(on[mesh.edges[:, 0]] & on[mesh.edges[:, 1]])


@pytest.mark.parametrize("fold,kind", [(np.radians(70), "V"), (np.radians(-40), "M")])
def test_crease_sense_from_strip_tags_and_from_dihedral(fold, kind):
    mesh, _ = folded_grid(fold)
    expected = crease_edges(mesh, 0.4)
    tagged = crease_assignment(mesh)
    assert tagged.source.startswith("face_data strip")
    assert np.array_equal(tagged.edges_with(kind), expected)
    assert np.allclose(tagged.edges_fold_angle[expected], fold)
    untagged = type(mesh)(mesh.vertices, mesh.faces_list())
    by_angle = crease_assignment(untagged)
    assert by_angle.source.startswith("dihedral")
    assert np.array_equal(by_angle.edges_with(kind), expected)
    assert len(tagged.edges_with("B")) == int(mesh.topology.boundary_edge_mask.sum())
    # below the threshold an untagged fold is not a crease
    assert len(crease_assignment(untagged, angle_threshold=abs(fold) + 0.01).edges_with(kind)) == 0


def test_flat_tagged_panel_has_creases_of_unknown_sense():
    mesh, _ = folded_grid(0.0)
    a = crease_assignment(mesh)
    assert len(a.edges_with("U")) == 4 and len(a.edges_with("M")) == len(a.edges_with("V")) == 0


def test_chain_edges_paths_and_loops():
    path = np.array([[3, 4], [1, 2], [2, 3]])
    chains = chain_edges(path)
    assert chains in ([[1, 2, 3, 4]], [[4, 3, 2, 1]])
    loop = np.array([[0, 1], [1, 2], [2, 0]])
    (c,) = chain_edges(loop)
    assert len(c) == 4 and c[0] == c[-1]
    tee = np.array([[0, 1], [1, 2], [1, 3]])
    chains = chain_edges(tee)
    assert sum(len(c) - 1 for c in chains) == 3


@pytest.fixture
def folded_pattern():
    mesh, _ = folded_grid(np.radians(60))
    dev = develop(mesh)
    assign = crease_assignment(mesh)
    return mesh, dev, assign, cut_pattern(mesh, dev.uv, assign, "P-12", label_edges=True)


def test_dxf_reads_back_in_millimetres(tmp_path, folded_pattern):
    mesh, dev, assign, pattern = folded_pattern
    path = tmp_path / "p.dxf"
    write_dxf(pattern, path)
    doc = ezdxf.readfile(path)
    assert doc.header["$INSUNITS"] == 4 and doc.header["$MEASUREMENT"] == 1
    assert {"CUT", "MOUNTAIN", "VALLEY", "LABEL"} <= {layer.dxf.name for layer in doc.layers}
    msp = doc.modelspace()
    (outline,) = msp.query('LWPOLYLINE[layer=="CUT"]')
    assert outline.closed
    pts = np.array([p[:2] for p in outline.get_points("xy")])
    expected = dev.uv[mesh.boundary_loops[0]] * 1000.0
    assert pts.shape == expected.shape
    assert np.max(np.abs(pts - expected)) <= 1e-6
    valleys = msp.query('LWPOLYLINE[layer=="VALLEY"]')
    assert len(valleys) == 1 and len(msp.query('LWPOLYLINE[layer=="MOUNTAIN"]')) == 0
    vpts = np.array([p[:2] for p in valleys[0].get_points("xy")])
    crease_vertices = np.unique(mesh.edges[assign.edges_with("V")])
    assert len(vpts) == len(crease_vertices)
    assert np.max(np.min(np.linalg.norm(vpts[:, None] - dev.uv[crease_vertices][None] * 1000, axis=2), axis=1)) <= 1e-6
    # valley line lies at 400 mm from the left edge of the flat sheet
    texts = [t.dxf.text for t in msp.query('TEXT[layer=="LABEL"]')]
    assert "P-12" in texts and any(t.startswith("e") for t in texts)


def test_svg_has_mm_size_viewbox_and_layers(tmp_path, folded_pattern):
    mesh, dev, _, pattern = folded_pattern
    path = tmp_path / "p.svg"
    write_svg(pattern, path)
    root = ET.parse(path).getroot()
    w, h = root.get("width"), root.get("height")
    assert w.endswith("mm") and h.endswith("mm")
    vb = [float(x) for x in root.get("viewBox").split()]
    assert vb[:2] == [0, 0] and np.isclose(vb[2], float(w[:-2])) and np.isclose(vb[3], float(h[:-2]))
    ext = dev.uv.max(axis=0) * 1000 - dev.uv.min(axis=0) * 1000
    assert np.isclose(vb[2], ext[0] + 2 * MARGIN_MM) and np.isclose(vb[3], ext[1] + 2 * MARGIN_MM)
    groups = {g.get("id"): g for g in root.iter(f"{SVG}g")}
    assert set(groups) == {"CUT", "VALLEY", "LABEL"}
    poly = groups["CUT"].find(f"{SVG}polygon")
    pts = np.array([[float(v) for v in p.split(",")] for p in poly.get("points").split()])
    lo = pattern.extent[0]
    back = np.column_stack([pts[:, 0] + lo[0] - MARGIN_MM, pattern.extent[1][1] + MARGIN_MM - pts[:, 1]])
    assert np.max(np.abs(back - dev.uv[mesh.boundary_loops[0]] * 1000)) <= 1e-6 + 1e-9


def test_writers_leave_nothing_behind_on_a_missing_directory(tmp_path, folded_pattern):
    from fabkit.errors import InputError

    pattern = folded_pattern[3]
    with pytest.raises(InputError, match="does not exist"):
        write_dxf(pattern, tmp_path / "nope" / "p.dxf")
    with pytest.raises(InputError, match="does not exist"):
        write_svg(pattern, tmp_path / "nope" / "p.svg")
    assert list(tmp_path.iterdir()) == []


def test_labels_sit_inside_the_sheet_and_closed_meshes_are_refused(folded_pattern):
    import shapely

    from fabkit.errors import MeshError
    from fabkit.mesh import PolyMesh

    mesh, dev, assign, pattern = folded_pattern
    sheet = shapely.Polygon(pattern.outlines[0])
    edge_labels = [lab for lab in pattern.labels if lab.text.startswith("e")]
    assert len(edge_labels) == int(mesh.topology.boundary_edge_mask.sum())
    assert all(sheet.contains(shapely.Point(lab.x, lab.y)) for lab in pattern.labels)
    tetra = PolyMesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float), [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    with pytest.raises(MeshError, match="no boundary"):
        cut_pattern(tetra, np.zeros((4, 2)), crease_assignment(tetra))
    with pytest.raises(ValueError, match="one row per vertex"):
        cut_pattern(mesh, dev.uv[:-1], assign)


def _label_texts_dxf(path):
    return [t.dxf.text for t in ezdxf.readfile(path).modelspace().query('TEXT[layer=="LABEL"]')]


@pytest.mark.parametrize("fold", [np.radians(70), np.radians(-40)])
def test_the_label_layer_says_which_face_is_up(tmp_path, fold):
    """A development that keeps the faces' turning sense shows the front (the side the face normals
    point to), a mirrored one the back; a valley folds toward the front, so with the front up it
    comes up toward the viewer, as the mark says."""
    from fabkit.cutfiles import face_up

    mesh, _ = folded_grid(fold)
    dev = develop(mesh)
    assign = crease_assignment(mesh)
    side = face_up(mesh, dev.uv)
    mirrored = dev.uv * np.array([-1.0, 1.0])
    assert {side, face_up(mesh, mirrored)} == {"front", "back"}
    # the fold's sense against the face normals: across a crease edge, the far face's centroid lies on
    # the normal side of the near face for a valley (edge faces share the crease)
    e = int(assign.edges_with("V" if fold > 0 else "M")[0])
    fa, fb = mesh.topology.edge_faces[e]
    fc = [mesh.vertices[mesh.faces_list()[f]].mean(axis=0) for f in (fa, fb)]
    n = mesh.face_normals[fa]
    assert (np.dot(fc[1] - fc[0], n) > 0) == (fold > 0)
    for uv, want in ((dev.uv, side), (mirrored, "back" if side == "front" else "front")):
        pattern = cut_pattern(mesh, uv, assign, "P-3")
        toward = "valleys" if want == "front" else "mountains"
        path = tmp_path / f"{want}.dxf"
        write_dxf(pattern, path)
        assert f"FACE UP: {want.upper()} ({toward} fold up)" in _label_texts_dxf(path)
        write_svg(pattern, tmp_path / f"{want}.svg")
        root = ET.parse(tmp_path / f"{want}.svg").getroot()
        label = next(g for g in root.iter(f"{SVG}g") if g.get("id") == "LABEL")
        assert f"FACE UP: {want.upper()} ({toward} fold up)" in [t.text for t in label.iter(f"{SVG}text")]


def test_unfold_with_a_sheet_notes_it_beside_the_face_up_mark(tmp_path):
    from fabkit.cli import main as fabkit_main

    obj = tmp_path / "panel.obj"
    assert fabkit_main(["generate", "reflect", "-o", str(obj), "-q", "--columns", "8", "--rows", "2"]) == 0
    dxf = tmp_path / "p.dxf"
    assert fabkit_main(["unfold", str(obj), "-o", str(tmp_path / "flat.obj"), "--dxf", str(dxf), "-q",
                        "--material", "5052-H32", "--thickness", "1mm", "--crease", "grooved"]) == 0
    (mark,) = [t for t in _label_texts_dxf(dxf) if t.startswith("FACE UP:")]
    assert "1 mm 5052-H32, design surface top" in mark and "valleys front, mountains back" in mark
