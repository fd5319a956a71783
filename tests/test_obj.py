"""OBJ reading/writing (polygons, order, data, precision) and trimesh exports."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from fabkit.errors import InputError, MeshError
from fabkit.io import load_mesh, save_mesh
from fabkit.io.export import export_mesh
from fabkit.io.obj import format_obj, load_obj, save_obj
from fabkit.mesh import PolyMesh
from io_meshes import MIXED_F, grid, mixed_mesh


def write(tmp_path, text: str, name: str = "m.obj"):
    p = tmp_path / name
    p.write_text(text)
    return p


# ---- round trips ---------------------------------------------------------------------------------
def test_round_trip_is_bitwise_exact_with_polygons_and_tags(tmp_path, rng):
    mesh = mixed_mesh(scale=rng.uniform(0.3, 3.0), jitter=1e-3)
    V = np.array(mesh.vertices)
    V[:, 2] = rng.normal(scale=1e-7, size=len(V))  # tiny values and full-precision mantissas
    V[3, 0] = 1e-300
    V[4, 1] = -0.0
    mesh = PolyMesh(V, mesh.faces_list(), face_data={**mesh.face_data, "score": rng.normal(size=5),
                                                      "label": np.array(["a", "bb", "c", "d", "eee"])},
                    vertex_data=mesh.vertex_data)
    p = tmp_path / "rt.obj"
    save_obj(mesh, p)
    back = load_obj(p)
    assert np.array_equal(back.vertices, mesh.vertices)
    assert np.signbit(back.vertices[4, 1])
    assert back.faces_list() == MIXED_F  # quads, pentagon and triangles in the same order
    assert set(back.face_data) == {"strip", "column", "middle", "score", "label"}
    for k, v in mesh.face_data.items():
        assert np.array_equal(back.face_data[k], v) and back.face_data[k].dtype == v.dtype
    for k, v in mesh.vertex_data.items():
        assert np.array_equal(back.vertex_data[k], v) and back.vertex_data[k].dtype == v.dtype
    save_obj(back, tmp_path / "rt2.obj")
    assert (tmp_path / "rt2.obj").read_bytes() == p.read_bytes()


def test_round_trip_keeps_nan_in_float_data(tmp_path):
    mesh = grid(2, 1).with_data(face_data={"w": np.array([np.nan, 0.25])})
    save_obj(mesh, tmp_path / "n.obj")
    back = load_obj(tmp_path / "n.obj")
    assert np.isnan(back.face_data["w"][0]) and back.face_data["w"][1] == 0.25


def test_written_text_layout():
    text = format_obj(grid(1, 1).with_data(face_data={"strip": np.array([3])}), header="panel P1\nmetres")
    lines = text.splitlines()
    assert lines[0].startswith("# fabkit OBJ")
    assert lines[1] == "# fabkit unit m"
    assert lines[2:4] == ["# panel P1", "# metres"]
    assert lines[4:8] == ["v 0.0 0.0 0.0", "v 1.0 0.0 0.0", "v 0.0 1.0 0.0", "v 1.0 1.0 0.0"]
    assert lines[8] == "f 1 2 4 3"
    assert lines[9] == "# fabkit face_data strip int64 [3]"


def test_other_tools_ignore_fabkit_comments(tmp_path):
    mesh = mixed_mesh()
    save_obj(mesh, tmp_path / "t.obj")
    tm = trimesh.load(tmp_path / "t.obj", process=False, force="mesh")
    assert len(tm.vertices) == mesh.n_vertices
    np.testing.assert_array_equal(tm.vertices, mesh.vertices)
    assert len(tm.faces) == int(np.sum(mesh.face_sizes - 2))  # trimesh triangulates; we do not


def test_writer_refuses_unsupported_data(tmp_path):
    with pytest.raises(ValueError, match="without whitespace"):
        format_obj(grid(1, 1).with_data(face_data={"bad name": np.array([1])}))
    with pytest.raises(ValueError, match="dtype object"):
        format_obj(grid(1, 1).with_data(face_data={"o": np.array([{}], dtype=object)}))
    assert not list(tmp_path.iterdir())


# ---- reading the forms other tools write ---------------------------------------------------------
def test_reads_texture_normal_corners_groups_materials_and_continuations(tmp_path):
    text = (
        "\ufeff# exported by some modeller\r\n"
        "mtllib panel.mtl\r\n"
        "o panel\r\n"
        "v 0 0 0 1.0\r\n"                  # w coordinate
        "v 1 0 0 0.5 0.5 0.5\r\n"          # vertex colour
        "v 1 1 0\r\n"
        "v 0 1 0  # trailing comment\r\n"
        "v 2 0 0\r\n"
        "vt 0 0\r\nvt 1 0\r\nvt 1 1\r\nvt 0 1\r\n"
        "vn 0 0 1\r\n"
        "g strip0\r\nusemtl steel\r\ns off\r\n"
        "f 1/1/1 2/2/1 3/3/1 4/4/1\r\n"
        "g strip1\r\ns 1\r\n"
        "f -4//1 \\\r\n -1//1 \\\r\n -3//1\r\n"   # negative indices and line continuations
        "l 1 2\r\n"
    )
    mesh = load_obj(write(tmp_path, text))
    assert mesh.faces_list() == [[0, 1, 2, 3], [1, 4, 2]]
    assert mesh.n_vertices == 5
    np.testing.assert_array_equal(mesh.vertices[1], [1, 0, 0])


def test_comment_ending_in_backslash_does_not_swallow_the_next_line(tmp_path):
    text = "# exported to C:\\panels\\\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    assert load_obj(write(tmp_path, text)).n_vertices == 3


def test_negative_indices_are_relative_to_vertices_so_far(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf 2 -1 3\n"
    assert load_obj(write(tmp_path, text)).faces_list() == [[0, 1, 2], [1, 3, 2]]


def test_unused_vertices_warn_and_keep_ids(tmp_path):
    text = "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n"
    with pytest.warns(UserWarning, match="1 unused vertices"):
        mesh = load_obj(write(tmp_path, text))
    assert mesh.n_vertices == 4 and mesh.faces_list() == [[1, 2, 3]]
    assert mesh.warnings and "unused" in mesh.warnings[0]


@pytest.mark.parametrize("text, needle", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4: face refers to vertex 4, but the vertices so far are 1..3"),
    ("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n", "line 1: face refers to vertex 1, but the vertices so far are none"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 3 4\n", "inconsistent orientation"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 3\n", "face 1 (line 5) repeats vertex 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# fabkit vertex_data p bool [true]\n",
     "line 5: fabkit vertex_data 'p' has 1 entries for 3 vertices"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# fabkit face_data s notadtype [1]\n", "line 5: cannot read"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# fabkit face_data s int8 [1000]\n", "line 5: cannot read fabkit"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# fabkit face_data s object [1]\n", "is not bool, int, float or str"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nbogus 1 2\n", "line 5: unknown OBJ statement bogus"),
    ("v 0 0 0\nv 1 0 0\nv 0 1_0 0\nf 1 2 3\n", "line 3: vertex coordinates '0 1_0 0' are not numbers"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3_\n", "line 4: face corner '3_' is not a vertex index"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 +3\n", "line 4: face corner '+3' is not a vertex index"),
])
def test_errors_name_file_and_line(tmp_path, text, needle):
    p = write(tmp_path, text)
    with pytest.raises(InputError) as err:
        load_obj(p)
    assert str(err.value).startswith(f"{p}: ")
    assert needle in str(err.value)


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_obj(tmp_path / "nope.obj")
    with pytest.raises(InputError, match="is a directory"):
        load_obj(tmp_path)


def test_mesh_errors_are_mesh_errors(tmp_path):
    with pytest.raises(MeshError):
        load_obj(write(tmp_path, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"))


# ---- exports and the typed entry points ----------------------------------------------------------
@pytest.mark.parametrize("suffix", ["ply", "glb"])
def test_export_keeps_vertex_ids(tmp_path, suffix):
    mesh = mixed_mesh()
    export_mesh(mesh, tmp_path / f"m.{suffix}")
    tm = trimesh.load(tmp_path / f"m.{suffix}", process=False, force="mesh")
    np.testing.assert_allclose(tm.vertices, mesh.vertices, atol=1e-7 if suffix == "glb" else 0)
    tris, tri_face = mesh.triangulate()
    np.testing.assert_array_equal(tm.faces, tris)
    assert [p.name for p in tmp_path.iterdir()] == [f"m.{suffix}"]  # no temporary files left


def test_export_stl_triangles(tmp_path):
    mesh = mixed_mesh()
    export_mesh(mesh, tmp_path / "m.stl")
    tm = trimesh.load(tmp_path / "m.stl", process=False, force="mesh")
    assert len(tm.faces) == int(np.sum(mesh.face_sizes - 2))
    np.testing.assert_allclose(tm.area, mesh.face_areas.sum(), rtol=1e-6)


def test_export_refuses_unknown_suffix(tmp_path):
    with pytest.raises(InputError, match="cannot export '.dae'"):
        export_mesh(grid(1, 1), tmp_path / "m.dae")
    with pytest.raises(InputError, match="output directory does not exist"):
        export_mesh(grid(1, 1), tmp_path / "missing" / "m.ply")
    assert not list(tmp_path.iterdir())


def test_load_mesh_and_save_mesh_dispatch(tmp_path):
    from fabkit.fold import FoldModel
    from fabkit.io import save_fold

    mesh = mixed_mesh()
    save_mesh(mesh, tmp_path / "a.obj")
    save_mesh(mesh, tmp_path / "a.ply")
    save_fold(FoldModel.from_mesh(mesh), tmp_path / "a.fold")
    for name in ("a.obj", "a.fold"):
        back = load_mesh(tmp_path / name)
        assert isinstance(back, PolyMesh) and back.faces_list() == MIXED_F
        np.testing.assert_array_equal(back.vertices, mesh.vertices)
        assert set(back.face_data) == {"strip", "column", "middle"}
    with pytest.raises(InputError, match="use .obj or .fold"):
        load_mesh(tmp_path / "a.ply")


def test_with_warnings_as_errors_good_file_is_quiet(tmp_path):
    save_obj(mixed_mesh(), tmp_path / "q.obj")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_obj(tmp_path / "q.obj").warnings == []
