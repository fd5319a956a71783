"""Face frames: exact answers on a grid folded along straight creases, triangulated files, errors."""
import numpy as np
import pytest

from fabkit.errors import InputError
from fabkit.fold import FoldModel
from fabkit.frames import (check_grip_face_moves, face_frames_of, face_groups, middle_row, middle_row_frames,
                           row_frames)
from fabkit.io.fold import load_fold, save_fold
from fold_fixtures import folded_grid_model, grid_panel


def _is_rigid(T):
    R = T[..., :3, :3]
    eye = np.broadcast_to(np.eye(3), R.shape)
    return np.allclose(R @ np.swapaxes(R, -1, -2), eye, atol=1e-14) and np.allclose(np.linalg.det(R), 1.0, atol=1e-14)


def test_flat_state_frames_are_axis_aligned():
    model = folded_grid_model(n_states=3)
    ff = middle_row_frames(model)
    np.testing.assert_array_equal(ff.faces, [6, 7, 8])  # middle column (i = 2) of a 5 x 3 grid
    np.testing.assert_array_equal(ff.strips, [0, 1, 2])
    T0 = ff.frames[0]
    for k, T in enumerate(T0):
        np.testing.assert_allclose(T[:3, 2], [0, 0, 1], atol=1e-15)   # front normal
        np.testing.assert_allclose(T[:3, 0], [0, 1, 0], atol=1e-15)   # across the creases
        np.testing.assert_allclose(T[:3, 3], [0.25, (k + 0.5) * 0.2, 0.0], atol=1e-15)
    assert _is_rigid(ff.frames)


@pytest.mark.parametrize("deg", [30.0, 60.0, 90.0, 135.0])
def test_folded_frames_match_the_rotation_about_the_crease(deg):
    a = np.radians(deg)
    model = folded_grid_model(angles=[a, a], clamp_strip=1, n_states=2)
    T = middle_row_frames(model).frames[-1]
    # strip 1 is clamped and stays flat; strips 0 and 2 turn up toward the front (valley)
    np.testing.assert_allclose(T[1][:3, 2], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(T[2][:3, 2], [0, -np.sin(a), np.cos(a)], atol=1e-14)
    np.testing.assert_allclose(T[2][:3, 0], [0, np.cos(a), np.sin(a)], atol=1e-14)
    np.testing.assert_allclose(T[0][:3, 2], [0, np.sin(a), np.cos(a)], atol=1e-14)
    # centroid of strip 2's face: crease at y = 0.4, half a strip (0.1 m) out along the turned strip
    np.testing.assert_allclose(T[2][:3, 3], [0.25, 0.4 + 0.1 * np.cos(a), 0.1 * np.sin(a)], atol=1e-14)
    assert _is_rigid(T)


def test_triangulated_file_gives_the_same_frames(tmp_path):
    quads = middle_row_frames(folded_grid_model(n_states=5))
    tri_model = folded_grid_model(n_states=5, triangulate=True)
    tris = middle_row_frames(tri_model)
    np.testing.assert_array_equal(tris.faces, quads.faces)
    np.testing.assert_allclose(tris.frames, quads.frames, atol=1e-15)
    # through a FOLD file (mm on disk, metres in memory)
    path = tmp_path / "seq.fold"
    save_fold(tri_model, path)
    back = middle_row_frames(load_fold(path))
    np.testing.assert_allclose(back.frames, quads.frames, atol=1e-13)
    assert back.n_states == 5
    np.testing.assert_allclose(back.of_face(8), quads.frames[:, 2], atol=1e-13)


def test_rows_of_one_face_use_the_first_edge():
    mesh = grid_panel(n_strips=1, n_columns=3)
    g = face_groups(mesh.faces_list(), mesh.face_data)
    row = middle_row(g)
    T = row_frames(g, np.asarray(mesh.vertices), row)
    np.testing.assert_allclose(T[0, 0, :3, 0], [1, 0, 0], atol=1e-15)


def test_model_without_frames_uses_the_key_frame():
    model = FoldModel.from_mesh(grid_panel())
    ff = middle_row_frames(model)
    assert ff.n_states == 1


def test_missing_middle_tags_is_an_input_error():
    mesh = grid_panel()
    data = {k: v for k, v in mesh.face_data.items() if k != "middle"}
    g = face_groups(mesh.faces_list(), data)
    with pytest.raises(InputError, match="no middle-row faces"):
        middle_row(g, source="x.fold")


def test_two_middle_faces_in_one_strip():
    mesh = grid_panel()
    data = dict(mesh.face_data)
    mid = np.array(data["middle"])
    mid[0] = 1  # column 0, strip 0
    data["middle"] = mid
    with pytest.raises(InputError, match="more than one middle-row face in strip 0"):
        middle_row(face_groups(mesh.faces_list(), data))


def test_polygon_members_must_agree_on_tags():
    mesh = grid_panel()
    data = dict(mesh.face_data)
    data["polygon"] = np.zeros(mesh.n_faces, dtype=np.int64)  # every face claims to be polygon 0
    with pytest.raises(InputError, match="disagree on faces_fabkit:strip"):
        face_groups(mesh.faces_list(), data, source="x.fold")


def test_zero_area_face_is_refused():
    mesh = grid_panel()
    g = face_groups(mesh.faces_list(), mesh.face_data)
    V = np.array(mesh.vertices)
    V[:, 1] = 0.0  # squash everything onto a line
    with pytest.raises(InputError, match="zero area"):
        row_frames(g, V, middle_row(g))


def test_one_face_without_tags():
    model = folded_grid_model(n_states=3)
    untagged = FoldModel.from_mesh(model.mesh().with_vertices(model.vertices_coords), frames=model.frames)
    object.__setattr__(untagged, "faces_data", {})
    ff = face_frames_of(untagged, 8)
    assert ff.faces.tolist() == [8] and ff.frames.shape == (3, 1, 4, 4)
    # same origin and normal as the middle-row frame; x along the face's first edge (+x here)
    row = middle_row_frames(model).of_face(8)
    np.testing.assert_allclose(ff.frames[:, 0, :3, 2:], row[:, :3, 2:], atol=1e-15)
    np.testing.assert_allclose(ff.frames[0, 0, :3, 0], [1, 0, 0], atol=1e-15)
    with pytest.raises(InputError, match="face 99 does not exist"):
        face_frames_of(untagged, 99, source="x.fold")


@pytest.mark.parametrize("triangulate", [False, True])
def test_untagged_file_gets_the_inferred_middle_row(triangulate):
    model = folded_grid_model(n_states=4, angles=[np.radians(40), np.radians(-30)], triangulate=triangulate)
    tagged = middle_row_frames(model)
    keep = {"polygon": model.faces_data["polygon"]} if triangulate else {}
    import dataclasses

    untagged = dataclasses.replace(model, faces_data=keep)
    ff = middle_row_frames(untagged)
    np.testing.assert_array_equal(ff.faces, tagged.faces)       # the middle column, by strip
    np.testing.assert_allclose(ff.frames, tagged.frames, atol=1e-12)
    check_grip_face_moves(ff, int(ff.faces[0]))
    with pytest.raises(InputError, match="folds nothing"):
        check_grip_face_moves(ff, int(ff.faces[1]))             # the clamped middle strip
    with pytest.raises(InputError, match="clamped face"):
        check_grip_face_moves(ff, int(ff.faces[0]), clamped=int(ff.faces[0]))
