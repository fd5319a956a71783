"""The cell model: panel as convex pieces, grip-face exclusion, clearance margins, names."""
import copy
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robot import kinematics as kin
from robot.cell import Shape, load_cell
from sim.model import GROUP_ARM, GROUP_ENV, GROUP_PANEL, GROUP_TOOL, build_cell_model
from sim.panel import interpolate_poses, panel_model, panel_pieces, piece_poses

CELLS = Path(__file__).resolve().parent.parent / "cells"


def _T(p=(0, 0, 0), rotvec=(0, 0, 0)):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = p
    return T


# a flat two-face strip, 0.2 m x 0.1 m, crease along x = 0.1
FLAT = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0], [0.2, 0, 0], [0.2, 0.1, 0]], float)
FACES = [[0, 1, 2, 3], [1, 4, 5, 2]]


def _v_fold(angle):
    """The strip with the second face turned up by `angle` about the crease (exact rigid fold)."""
    V = FLAT.copy()
    R = Rotation.from_rotvec([0, -angle, 0])
    V[[4, 5]] = R.apply(FLAT[[4, 5]] - [0.1, 0, 0]) + [0.1, 0, 0]
    return V


def test_piece_poses_reproduce_a_rigid_fold_exactly():
    pieces = panel_pieces(FLAT, FACES, 0.002)
    assert len(pieces) == 2 and pieces.local_vertices[0].shape == (8, 3)
    for angle in (0.0, 0.7, 2.0):
        V = _v_fold(angle)
        pos, quat, res = piece_poses(pieces, V)
        assert res.max() < 1e-12
        for f, face in enumerate(FACES):
            R = Rotation.from_quat(quat[f][[1, 2, 3, 0]])
            np.testing.assert_allclose(R.apply(pieces.local_polygons[f]) + pos[f], V[np.unique(face)], atol=1e-12)


def test_interpolated_poses_hit_the_states_and_stay_between():
    P = panel_model(FLAT, FACES, np.stack([_v_fold(0.0), _v_fold(1.0)]), np.eye(4))
    for k in (0, 1):
        pos, quat = P.poses_at(k)
        np.testing.assert_allclose(pos, P.pos[k])
        np.testing.assert_allclose(np.abs(np.sum(quat * P.quat[k], axis=1)), 1.0, atol=1e-12)
    _, q_half = interpolate_poses(P.pos, P.quat, 0.5)
    R0 = Rotation.from_quat(P.quat[0, 1][[1, 2, 3, 0]])
    turn = (Rotation.from_quat(q_half[1][[1, 2, 3, 0]]) * R0.inv()).magnitude()
    assert turn == pytest.approx(0.5, abs=1e-2)  # normalised lerp of a 1 rad turn: 0.5 rad to 2nd order


def _cell_with(obstacles=(), shapes=None, clearance=0.01):
    cell = load_cell(CELLS / "ur5e_bench.toml")
    tool = copy.copy(cell.tool)
    if shapes is not None:
        object.__setattr__(tool, "shapes", tuple(shapes))
    limits = copy.copy(cell.limits)
    object.__setattr__(limits, "clearance", clearance)
    new = copy.copy(cell)
    object.__setattr__(new, "tool", tool)
    object.__setattr__(new, "obstacles", tuple(cell.obstacles) + tuple(obstacles))
    object.__setattr__(new, "limits", limits)
    return new


def _contacts(m, names, q, panel=None, state=0.0):
    d = mujoco.MjData(m)
    d.qpos[:] = q
    if panel is not None:
        d.mocap_pos[:], d.mocap_quat[:] = panel.poses_at(state)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_collision(m, d)
    return {(names.geom[c.geom1], names.geom[c.geom2]): c.dist for c in d.contact[:d.ncon]}


def test_names_groups_and_margins():
    cell = load_cell(CELLS / "ur10e_fold_table.toml")
    P = panel_model(FLAT, FACES, FLAT[None], cell.fixture, grip_face=1)
    m, names = build_cell_model(cell, P)
    group = dict(zip(names.geom, names.geom_group))
    assert group["wrist_3"] == GROUP_ARM and group["suction_cup"] == GROUP_TOOL
    assert group["fold_table"] == GROUP_ENV and group["face_0"] == GROUP_PANEL
    margin = dict(zip(names.geom, m.geom_margin))
    assert margin["fold_table"] == margin["face_1"] == pytest.approx(cell.limits.clearance + 0.05)
    assert margin["wrist_3"] == margin["suction_cup"] == 0.0
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "tcp")
    # the tcp site is flange . tcp in world
    d.qpos[:] = cell.robot.home
    mujoco.mj_kinematics(m, d)
    want = cell.robot.base_pose @ kin.fk_tcp(cell.model, cell.robot.home, cell.tool.tcp)
    np.testing.assert_allclose(d.site_xpos[site], want[:3, 3], atol=1e-12)
    np.testing.assert_allclose(d.site_xmat[site].reshape(3, 3), want[:3, :3], atol=1e-12)


def _down(cell, p_panel):
    """World TCP pose pointing down onto the panel at point `p_panel` (panel frame)."""
    return cell.fixture @ _T(p_panel, (np.pi, 0, 0))


def _tool_at(cell, tcp_world):
    """Joints that put the TCP at a world pose, on the home configuration's branch."""
    T = cell.world_to_base @ tcp_world
    home = cell.robot.home
    return kin.select_nearest(kin.ik(cell.model, T, cell.tool.tcp), home, model=cell.model,
                              branch=kin.branch_signs(cell.model, home))


def test_folded_panel_is_not_its_convex_hull():
    """A probe inside the V of a folded panel touches neither wing (one mesh would be its hull)."""
    cell = _cell_with(clearance=0.0)
    V = _v_fold(np.radians(120))  # wings at 60 deg to each other... the right wing rises steeply
    P = panel_model(FLAT, FACES, V[None], cell.fixture, grip_face=None)
    m, names = build_cell_model(cell, P)
    # the point above the crease, inside the V, 2 cm up
    target = _down(cell, [0.1, 0.05, 0.045])
    q = _tool_at(cell, target)
    found = _contacts(m, names, q, P)
    assert not [k for k, dist in found.items() if "face" in k[1] and dist < 0], found
    # pushed down onto the crease it touches the left face
    q2 = _tool_at(cell, _down(cell, [0.05, 0.05, -0.005]))
    found = _contacts(m, names, q2, P)
    assert any(k[1] == "face_0" and d < 0 for k, d in found.items()), found


def test_grip_face_contact_is_excluded_and_other_faces_are_not():
    cell = _cell_with(clearance=0.01)
    P = panel_model(FLAT, FACES, FLAT[None], cell.fixture, grip_face=1)
    m, names = build_cell_model(cell, P)
    # the suction cup (ending 2 mm short of the TCP) pressed 3 mm into the middle of face 1 (grip face)
    q = _tool_at(cell, _down(cell, [0.15, 0.05, -0.005]))
    found = _contacts(m, names, q, P)
    assert not any("face_1" in k for k in found), found
    # the same press on face 0 is a collision
    q = _tool_at(cell, _down(cell, [0.05, 0.05, -0.005]))
    found = _contacts(m, names, q, P)
    assert any(k[1] == "face_0" and d < 0 for k, d in found.items()), found


def test_clearance_margin_reports_the_distance():
    cell = _cell_with(clearance=0.02)
    tcp_world = _down(cell, [0.0, 0.0, 0.2])
    # the wall 7 mm beside the suction cup (radius 25 mm)
    wall = Shape(name="probe_wall", kind="box", pose=_T(tcp_world[:3, 3] + [0.025 + 0.007 + 0.01, 0, 0]),
                 size=(0.01, 0.03, 0.03))
    cell = _cell_with(obstacles=[wall], clearance=0.02)
    m, names = build_cell_model(cell)
    found = _contacts(m, names, _tool_at(cell, tcp_world))
    assert found[("suction_cup", "probe_wall")] == pytest.approx(0.007, abs=1e-6)


def test_shoulder_is_not_paired_with_the_mounting_table_but_the_upper_arm_is():
    cell = load_cell(CELLS / "ur5e_bench.toml")
    m, names = build_cell_model(cell)
    q = np.array(cell.robot.home, float)
    found = _contacts(m, names, q)
    assert not any("shoulder" == a for a, _ in found)
    q[1] = 0.0  # upper arm horizontal, elbow bent down into the bench
    q[2] = 1.6
    found = _contacts(m, names, q)
    assert any(a in ("elbow", "forearm") and b in ("bench", "fixture_block") and d < 0
               for (a, b), d in found.items()), found
