"""The one panel loader: units, welding, winding, quads re-merged, FOLD of other tools, .3dm, SVG."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fabkit.errors import InputError, MeshError
from fabkit.io import hygiene
from fabkit.io.load import load_fold_model, load_panel
from fabkit.io.save import save_panel
from panel_inputs import (fold_other_tool, plain_obj, reflect, rhino_3dm, shuffled, triangulated,
                                unwelded)


def _same_shape(a, b, atol=1e-12):
    """Same vertex set (order free) and same faces up to that renumbering and corner rotation."""
    from scipy.spatial import cKDTree

    d, j = cKDTree(b.vertices).query(a.vertices)
    assert d.max() <= atol
    assert len(set(j.tolist())) == a.n_vertices == b.n_vertices
    canon = lambda f: min(tuple(f[k:] + f[:k]) for k in range(len(f)))  # noqa: E731
    fa = sorted(canon([int(j[i]) for i in f]) for f in a.faces_list())
    fb = sorted(canon(list(f)) for f in b.faces_list())
    assert fa == fb


# ---- units -----------------------------------------------------------------------------------------
def test_millimetre_obj_gets_a_note_and_units_flag_scales(tmp_path):
    V, F = reflect()
    p = plain_obj(tmp_path / "mm.obj", V * 1000, F)
    mesh, info = load_panel(p)
    assert info.unit == "m" and info.unit_source == "assumed"
    assert any("pass --units mm" in n for n in info.notes), info.notes
    mesh, info = load_panel(p, units="mm")
    assert info.unit == "mm" and info.unit_source == "from --units" and not info.notes
    np.testing.assert_allclose(mesh.vertices, V, rtol=0, atol=1e-15)


def test_fabkit_obj_declares_metres_and_refuses_a_contradicting_flag(tmp_path):
    V, F = reflect()
    mesh, _ = load_panel(plain_obj(tmp_path / "mm.obj", V * 1000, F), units="mm")
    save_panel(mesh, tmp_path / "out.obj")
    assert "# fabkit unit m\n" in (tmp_path / "out.obj").read_text()
    back, info = load_panel(tmp_path / "out.obj")
    assert info.unit_source == "from the file" and np.array_equal(back.vertices, mesh.vertices)
    with pytest.raises(InputError, match="declares its unit as m but --units mm"):
        load_panel(tmp_path / "out.obj", units="mm")


def test_fold_without_frame_unit_takes_units(tmp_path):
    V, F = reflect()
    p = fold_other_tool(tmp_path / "cp.fold", V * 1000, F, {})
    model, info = load_fold_model(p)
    assert info.unit == "unit" or info.unit == "m"
    assert any("--units mm" in n for n in info.notes)
    model, info = load_fold_model(p, units="mm")
    np.testing.assert_allclose(model.vertices_coords, V, atol=1e-15)
    with pytest.raises(InputError, match="declares its unit as cm"):
        load_fold_model(fold_other_tool(tmp_path / "cm.fold", V * 100, F, {}, unit="cm"), units="mm")


# ---- hygiene -----------------------------------------------------------------------------------------
def test_weld_reports_and_maps_every_vertex():
    V, F = reflect()
    W, G = unwelded(V, F)
    w = hygiene.weld(W, G)
    assert w.merged == len(W) - len(V)
    np.testing.assert_array_equal(w.vertices[w.index_map], W)  # every old vertex -> its welded copy
    assert np.all(np.diff(w.kept) > 0)  # kept in the original order
    same = hygiene.weld(V, F)
    assert same.merged == 0 and np.array_equal(same.index_map, np.arange(len(V)))


def test_weld_refuses_a_tolerance_that_collapses_faces():
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1e-9, 0], [0, 1, 0.0]])
    with pytest.raises(MeshError, match="face 0 collapses"):
        hygiene.weld(V, [[0, 1, 2, 3]], rtol=1e-6)


def test_orient_repairs_flipped_faces_and_refuses_a_moebius_strip():
    V, F = reflect()
    G = [f[::-1] if k % 3 == 0 else list(f) for k, f in enumerate(F)]
    o = hygiene.orient(V, G)
    assert o.faces == [list(f) for f in F] and len(o.flipped) == len(range(0, len(F), 3))
    # flat panel wound clockwise throughout: turned to face +z
    flat = [[0, 1, 2, 3]]
    Vf = np.array([[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0.0]])
    assert hygiene.orient(Vf, flat).faces == [[3, 2, 1, 0]]
    n = 12  # a Moebius strip: a band of quads closed with a half twist
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = [[np.cos(a) * (1 + s * np.cos(a / 2)), np.sin(a) * (1 + s * np.cos(a / 2)), s * np.sin(a / 2)]
            for a in t for s in (-0.2, 0.2)]
    quads = [[2 * i, 2 * i + 1, 2 * i + 3, 2 * i + 2] for i in range(n - 1)] + [[2 * n - 2, 2 * n - 1, 0, 1]]
    with pytest.raises(MeshError, match="not orientable"):
        hygiene.orient(np.array(ring), quads)


def test_triangulated_reflect_panel_merges_back_to_its_quads(tmp_path):
    V, F = reflect()
    p = plain_obj(tmp_path / "tri.obj", V, triangulated(F))
    mesh, info = load_panel(p)
    assert info.merged_quads == len(F) and mesh.n_faces == len(F)
    assert mesh.faces_list() == [list(f) for f in F] or sorted(map(sorted, mesh.faces_list())) == \
        sorted(map(sorted, F))
    _same_shape(mesh, load_panel(plain_obj(tmp_path / "q.obj", V, F))[0])


def test_flat_triangulated_grid_merges_to_its_squares():
    nx, ny = 5, 4
    xs, ys = np.meshgrid(np.arange(nx + 1) * 0.1, np.arange(ny + 1) * 0.07)
    V = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    quads = [[j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i]
             for j in range(ny) for i in range(nx)]
    m = hygiene.merge_triangle_pairs(V, triangulated(quads))
    assert m.merged == len(quads)
    assert sorted(map(sorted, m.faces)) == sorted(map(sorted, quads))


def test_shuffled_unwelded_flipped_triangulated_millimetres_is_the_same_panel(tmp_path):
    V, F = reflect()
    S, G, _ = shuffled(V * 1000, F)
    W, H = unwelded(S, triangulated(G))
    H = [h[::-1] if k % 4 == 1 else h for k, h in enumerate(H)]
    mesh, info = load_panel(plain_obj(tmp_path / "messy.obj", W, H), units="mm")
    assert info.welded == len(W) - len(V) and info.merged_quads == len(F) and len(info.flipped_faces)
    assert len(info.vertex_map) == len(W)
    _same_shape(mesh, load_panel(plain_obj(tmp_path / "clean.obj", V, F))[0], atol=1e-15)
    # front side kept: the face normals agree with the clean panel's
    clean = load_panel(plain_obj(tmp_path / "c2.obj", V, F))[0]
    assert np.dot(mesh.face_normals.sum(axis=0), clean.face_normals.sum(axis=0)) > 0


# ---- FOLD of other tools ---------------------------------------------------------------------------------
def _creases(V, F):
    """Interior edges between the reflect panel's two halves (y of the crease), assigned V."""
    from fabkit.mesh import PolyMesh
    from fabkit.cutfiles.creases import crease_assignment

    m = PolyMesh(V, F)
    a = crease_assignment(m)
    return {(int(u), int(v)): c for (u, v), c in zip(m.edges.tolist(), a.edges_assignment.tolist())}, a


@pytest.mark.parametrize("style", ["lower", "triangles", "no-angles", "angles", "flipped-minority"])
def test_fold_in_other_tools_conventions(tmp_path, style):
    V, F = reflect()
    sides, a = _creases(V, F)
    faces = triangulated(F) if style == "triangles" else [list(f) for f in F]
    if style == "flipped-minority":
        faces = [f[::-1] if k in (2, 5) else f for k, f in enumerate(faces)]
    flat = np.array(V)
    from fabkit.io.load import load_panel as lp
    from fabkit.unfold import develop
    from fabkit.mesh import PolyMesh

    dev = develop(PolyMesh(V, F))
    flat = np.column_stack([dev.uv, np.zeros(len(V))])
    p = fold_other_tool(tmp_path / "cp.fold", flat, faces, sides, unit="m", lower=style == "lower",
                        angles=style == "angles", frames=[V])
    mesh, info = lp(p)  # the folded frame
    assert mesh.n_faces == len(F)
    np.testing.assert_allclose(mesh.vertices, V, atol=1e-15)
    # M/V kept as tags: creases become strips, every side keeps its letter
    assert "assignment" in mesh.face_data and "strip" in mesh.face_data
    letters = {}
    for f, s in zip(mesh.faces_list(), mesh.face_data["assignment"].tolist()):
        for (u, v), c in zip(zip(f, f[1:] + f[:1]), s):
            letters[(min(u, v), max(u, v))] = c
    assert {e: c for e, c in letters.items() if c in "MV"} == {e: c for e, c in sides.items() if c in "MV"}
    if style == "lower":
        assert any("lower-case" in n for n in info.notes)
    if style == "flipped-minority":
        assert any("faces turned" in n for n in info.notes)
    key, _ = lp(p, state="key")
    assert np.all(key.vertices[:, 2] == 0.0)


def test_fold_to_obj_keeps_mountain_valley(tmp_path):
    V, F = reflect()
    sides, _ = _creases(V, F)
    sides = {e: ("M" if c == "V" else c) for e, c in sides.items()}  # a mountain crease pattern, flat only
    flatV = np.array(V)
    flatV[:, 2] = 0.0
    from fabkit.unfold import develop
    from fabkit.mesh import PolyMesh

    uv = develop(PolyMesh(V, F)).uv
    p = fold_other_tool(tmp_path / "cp.fold", np.column_stack([uv, np.zeros(len(V))]), F, sides, unit="mm")
    mesh, _ = load_panel(p)
    save_panel(mesh, tmp_path / "cp.obj")
    back, _ = load_panel(tmp_path / "cp.obj")
    assert back.face_data["assignment"].tolist() == mesh.face_data["assignment"].tolist()
    assert sum(s.count("M") for s in back.face_data["assignment"].tolist()) == 2 * sum(
        c == "M" for c in sides.values())


# ---- Rhino ---------------------------------------------------------------------------------------------
def test_3dm_written_by_rhino3dm_in_millimetres(tmp_path):
    V, F = reflect()
    p = rhino_3dm(tmp_path / "panel.3dm", V * 1000, triangulated(F))
    mesh, info = load_panel(p)
    assert info.unit == "mm" and info.unit_source == "from the file" and info.merged_quads == len(F)
    _same_shape(mesh, load_panel(plain_obj(tmp_path / "q.obj", V, F))[0], atol=1e-15)


def test_fabkit_3dm_reads_back_in_rhino3dm_with_layers_and_tags(tmp_path):
    import rhino3dm

    from fabkit.generate.reflect import reflect_panel

    panel = reflect_panel(columns=8, rows=3)
    save_panel(panel, tmp_path / "out.3dm", header="P1")
    model = rhino3dm.File3dm.Read(str(tmp_path / "out.3dm"))
    layers = [model.Layers[i].Name for i in range(len(model.Layers))]
    assert {"PANEL", "CUT", "VALLEY"} <= set(layers)
    assert model.Settings.ModelUnitSystem == rhino3dm.UnitSystem.Meters
    on = {}
    for o in model.Objects:
        on.setdefault(layers[o.Attributes.LayerIndex], []).append(o)
    (mesh_obj,) = on["PANEL"]
    tags = mesh_obj.Attributes.GetUserStrings()
    tags = dict(tags.items() if isinstance(tags, dict) else tags)
    assert tags["fabkit face_data strip"].startswith("int64 [")
    assert len(on["VALLEY"]) >= 1 and len(on["CUT"]) == 1
    back, info = load_panel(tmp_path / "out.3dm")
    assert np.array_equal(back.vertices, panel.vertices) and back.faces_list() == panel.faces_list()
    assert np.array_equal(back.face_data["strip"], panel.face_data["strip"])


def test_3dm_with_two_meshes_and_no_panel_layer_is_refused(tmp_path):
    import rhino3dm

    V, F = reflect()
    model = rhino3dm.File3dm()
    for _ in range(2):
        m = rhino3dm.Mesh()
        for x, y, z in V.tolist():
            m.Vertices.AddPoint3d(x, y, z)
        for f in F:
            m.Faces.AddFace(*f)
        model.Objects.AddMesh(m)
    model.Write(str(tmp_path / "two.3dm"), 8)
    with pytest.raises(InputError, match="2 meshes"):
        load_panel(tmp_path / "two.3dm")


# ---- SVG crease patterns -------------------------------------------------------------------------------
SVG = """<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="100mm" viewBox="0 0 400 200">
<g style="stroke:#000;fill:none"><rect x="0" y="0" width="400" height="200"/></g>
<line x1="200" y1="0" x2="200" y2="200" style="stroke:#ff0000"/>
<path d="M 100 0 l 0 200" stroke="blue" stroke-opacity="0.5"/>
<polyline points="200,100 400,100" stroke="rgb(255,255,0)"/>
</svg>
"""


def test_svg_crease_pattern_in_origami_simulator_colours(tmp_path):
    p = tmp_path / "cp.svg"
    p.write_text(SVG)
    mesh, info = load_panel(p)
    assert info.unit == "mm" and info.format == "svg"
    np.testing.assert_allclose(np.ptp(mesh.vertices, axis=0), [0.2, 0.1, 0.0], atol=1e-12)
    assert mesh.n_faces == 4 and np.all(mesh.vertices[:, 2] == 0)
    letters = "".join(mesh.face_data["assignment"].tolist())
    assert letters.count("M") == 4  # the mountain line is split at the facet line: 2 edges, 2 faces each
    assert letters.count("V") == 2 and letters.count("F") == 2
    assert any("partly transparent" in n for n in info.notes)
    assert np.all(mesh.face_normals[:, 2] > 0)


def test_svg_with_unknown_colours_or_curves_is_refused(tmp_path):
    (tmp_path / "a.svg").write_text(SVG.replace("#ff0000", "#123456"))
    with pytest.raises(InputError, match="unknown colour #123456"):
        load_panel(tmp_path / "a.svg")
    (tmp_path / "b.svg").write_text(SVG.replace("M 100 0 l 0 200", "M 100 0 C 1 2 3 4 100 200"))
    with pytest.raises(InputError, match="curve"):
        load_panel(tmp_path / "b.svg")


def test_inches_and_centimetres(tmp_path):
    V, F = reflect()
    for unit, per in (("in", 0.0254), ("cm", 0.01)):
        mesh, info = load_panel(plain_obj(tmp_path / f"{unit}.obj", V / per, F), units=unit)
        np.testing.assert_allclose(mesh.vertices, V, rtol=0, atol=1e-15)
        assert info.unit == unit and not info.notes
    with pytest.raises(InputError, match="unknown unit 'ft'"):
        load_panel(tmp_path / "in.obj", units="ft")


def test_cli_units_flag_is_on_every_reading_command():
    from fabkit.cli import build_parser

    for name in ("relax", "unfold", "refold", "toolpath", "info", "panels"):
        parser = build_parser(only=name)
        sub = next(a for a in parser._actions if a.dest == "command").choices[name]
        assert any("--units" in a.option_strings for a in sub._actions), name
