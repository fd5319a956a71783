"""The cell model: panel as convex pieces, grip-face exclusion, clearance margins, names."""
import copy
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robot import kinematics as kin
from robot.cell import Shape, load_cell
from sim.arm import part_name
from sim.model import CLEARANCE_WINDOW, GROUP_ARM, GROUP_ENV, GROUP_PANEL, GROUP_TOOL, build_cell_model
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
    assert margin["fold_table"] == pytest.approx(cell.limits.clearance + CLEARANCE_WINDOW)
    assert margin["face_1"] == pytest.approx(cell.limits.clearance)
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


def _tip_gap(cell):
    """How far the tool's collision shapes stop short of the TCP along the tool axis (m)."""
    tip = max(sh.pose[2, 3] + (sh.size[1] if sh.kind in ("cylinder", "capsule") else sh.size[-1])
              for sh in cell.tool.shapes)
    return float(cell.tool.tcp[2, 3] - tip)


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
    """The tool over face 0 of an L-folded strip (wing standing up at the crease) touches neither
    piece; as one mesh the panel would be its hull, which contains the tool."""
    cell = _cell_with(clearance=0.03)  # the panel's margin: distances up to 30 mm are reported
    V = _v_fold(np.radians(90))
    P = panel_model(FLAT, FACES, V[None], cell.fixture, grip_face=None)
    m, names = build_cell_model(cell, P)
    gap = _tip_gap(cell)
    # tool bottom 2 cm above face 0, its axis 5 cm from the standing wing: inside the L's hull
    q = _tool_at(cell, _down(cell, [0.05, 0.05, 0.02 - gap]))
    tool = {sh.name for sh in cell.tool.shapes}
    found = _contacts(m, names, q, P)
    assert not [k for k, dist in found.items() if k[0] in tool and k[1].startswith("face") and dist < 0], found
    assert found[("suction_cup", "face_0")] == pytest.approx(0.02 - 0.0005, abs=1e-6)  # half the sheet thickness
    # pushed 3 mm into face 0 it touches it
    q2 = _tool_at(cell, _down(cell, [0.05, 0.05, -gap - 0.003]))
    found = _contacts(m, names, q2, P)
    assert found[("suction_cup", "face_0")] == pytest.approx(-0.0035, abs=1e-6)


def test_grip_face_contact_is_excluded_and_other_faces_are_not():
    cell = _cell_with(clearance=0.01)
    P = panel_model(FLAT, FACES, FLAT[None], cell.fixture, grip_face=1)
    m, names = build_cell_model(cell, P)
    # the tool pressed 3 mm into the middle of face 1 (the grip face)
    gap = _tip_gap(cell)
    q = _tool_at(cell, _down(cell, [0.15, 0.05, -gap - 0.003]))
    found = _contacts(m, names, q, P)
    assert not any("face_1" in k for k in found), found
    # the same press on face 0 is a collision
    q = _tool_at(cell, _down(cell, [0.05, 0.05, -gap - 0.003]))
    found = _contacts(m, names, q, P)
    assert found[("suction_cup", "face_0")] == pytest.approx(-0.0035, abs=1e-6)


def test_clearance_margin_reports_the_distance():
    cell = _cell_with(clearance=0.02)
    cup = next(sh for sh in cell.tool.shapes if sh.name == "suction_cup")
    tcp_world = _down(cell, [0.25, 0.25, 0.2])
    # a small block level with the cup's middle, its face 7 mm beside the cup's side
    up = cell.tool.tcp[2, 3] - cup.pose[2, 3]  # cup centre above the TCP (tool pointing down)
    centre = tcp_world[:3, 3] + [0.0, 0.0, up] + tcp_world[:3, 0] * (cup.size[0] + 0.007 + 0.004)
    block = Shape(name="probe_block", kind="box", pose=_T(centre, Rotation.from_matrix(tcp_world[:3, :3]).as_rotvec()),
                  size=(0.004, 0.01, 0.9 * cup.size[1]))
    cell = _cell_with(obstacles=[block], clearance=0.02)
    m, names = build_cell_model(cell)
    found = _contacts(m, names, _tool_at(cell, tcp_world))
    assert found[("suction_cup", "probe_block")] == pytest.approx(0.007, abs=1e-6)


def test_shoulder_is_never_paired_with_the_environment_but_other_links_are():
    """The shoulder housing turns about the base axis only (its distance to the mounting table is a
    layout constant): it never contacts obstacles; the other links do in random configurations."""
    cell = load_cell(CELLS / "ur5e_bench.toml")
    m, names = build_cell_model(cell)
    Q = np.random.default_rng(3).uniform(-np.pi, np.pi, (300, 6))
    pairs = set()
    for q in Q:
        pairs |= {k for k, d in _contacts(m, names, q).items() if d < 0}
    env = {o.name for o in cell.obstacles}
    assert not [(a, b) for a, b in pairs if "shoulder" in (a, b) and (b in env or a in env)]
    assert {"upper_arm", "forearm", "wrist_3"} <= {part_name(a) for a, b in pairs if b in env}
