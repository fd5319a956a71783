"""The toolpath check: good programs pass; an obstacle, a joint limit, a singularity and a too-fast
move each fail with their kind, the right names and the first offending waypoint."""
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robot import kinematics as kin
from robot.cell import load_cell, parse_cell
from sim.check import CheckSettings, Program, check_program, interpolate_program
from sim.programs import sweep_program

CELLS = Path(__file__).resolve().parent.parent / "cells"
UR5E = CELLS / "ur5e_bench.toml"
UR10E = CELLS / "ur10e_fold_table.toml"


def _kinds(report):
    return {p.kind for p in report.problems}


@pytest.fixture(scope="module")
def ur5e():
    return load_cell(UR5E)


@pytest.fixture(scope="module")
def ur10e():
    return load_cell(UR10E)


@pytest.mark.parametrize("path", [UR5E, UR10E], ids=lambda p: p.stem)
def test_sweep_over_the_fixture_passes_in_both_cells(path):
    cell = load_cell(path)
    prog = sweep_program(cell, 300, height=0.12)
    report, dense = check_program(prog, cell)
    assert report.ok, [p.detail for p in report.problems]
    assert report.problems == ()
    assert report.configs_checked == len(dense.q) > len(prog)
    assert report.cycle_time_s > 0
    js = report.to_json()
    assert js["format"] == "fabkit.check/2" and js["ok"] is True and js["problems"] == []


def test_interpolation_respects_the_step_sizes(ur5e):
    prog = sweep_program(ur5e, 120, height=0.12)
    s = CheckSettings()
    dense = interpolate_program(ur5e.model, prog, s)
    # every configuration that continues a move is within one joint step and one TCP step of the last
    moving = np.isfinite(dense.dt[1:])
    dq = np.max(np.abs(np.diff(dense.q, axis=0)), axis=1)[moving]
    T = kin.fk_tcp(ur5e.model, dense.q, ur5e.tool.tcp)
    travel = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)[moving]
    assert dq.max() <= s.step_joint_rad * 1.5 + 1e-12
    assert travel.max() <= s.step_tcp_m + 1e-9
    # linear moves: the interpolated TCP stays on the straight line between the waypoints
    for j in np.flatnonzero(~dense.at_waypoint)[:200]:
        i = dense.waypoint[j]
        a, b = prog.poses[i - 1][:3, 3], prog.poses[i][:3, 3]
        p = T[j, :3, 3]
        u = (b - a) / np.linalg.norm(b - a)
        assert np.linalg.norm((p - a) - u * ((p - a) @ u)) < 1e-9
    # every waypoint's own configuration is visited, in order
    np.testing.assert_array_equal(dense.waypoint[dense.at_waypoint], np.arange(len(prog)))


def _solid_cylinder_distance(p_local, radius, half_length):
    """Distance from a point (cylinder frame, axis z) to a solid cylinder (0 inside)."""
    dr = max(np.hypot(p_local[0], p_local[1]) - radius, 0.0)
    dz = max(abs(p_local[2]) - half_length, 0.0)
    return float(np.hypot(dr, dz))


def _tool_sphere_distance(cell, flange_base, centre_world, rho):
    """Exact surface distance between the tool's cylinders and a sphere (independent of MuJoCo)."""
    T = cell.robot.base_pose @ flange_base
    best = np.inf
    for shape in cell.tool.shapes:
        S = T @ shape.pose
        p = S[:3, :3].T @ (centre_world - S[:3, 3])
        best = min(best, _solid_cylinder_distance(p, shape.size[0], shape.size[1]) - rho)
    return best


def test_obstacle_in_the_way_names_the_pair_and_the_first_offending_waypoint(ur5e):
    prog = sweep_program(ur5e, 300, height=0.12)
    k = 137
    tcp_world = (ur5e.robot.base_pose @ prog.poses[k])[:3, 3]
    centre, rho = tcp_world, 0.03  # a ball round the TCP of waypoint k: the tool tip dips into it
    data = tomllib.loads(UR5E.read_text())
    data["obstacles"].append({"name": "probe", "kind": "sphere", "radius": rho,
                              "pose": [*centre.tolist(), 0.0, 0.0, 0.0]})
    cell = parse_cell(data, "variant.toml")
    report, _ = check_program(prog, cell)
    assert not report.ok
    # the same program in the unmodified cell passes: the probe is the only cause
    assert check_program(prog, ur5e)[0].ok

    # independent expectation: exact cylinder-sphere distances along the planned TCP path (the
    # flange pose follows from the TCP pose, no kinematics or MuJoCo needed)
    inv_tcp = np.linalg.inv(ur5e.tool.tcp)

    def first_below(limit):
        if _tool_sphere_distance(cell, prog.poses[0] @ inv_tcp, centre, rho) < limit:
            return 0
        for i in range(1, len(prog)):
            P0, P1 = prog.poses[i - 1], prog.poses[i]
            rv = Rotation.from_matrix(P0[:3, :3].T @ P1[:3, :3]).as_rotvec()
            for t in np.linspace(0.0, 1.0, 41)[1:]:
                T = np.eye(4)
                T[:3, :3] = P0[:3, :3] @ Rotation.from_rotvec(t * rv).as_matrix()
                T[:3, 3] = P0[:3, 3] + t * (P1[:3, 3] - P0[:3, 3])
                if _tool_sphere_distance(cell, T @ inv_tcp, centre, rho) < limit:
                    return i
        return None

    collisions = [p for p in report.problems if p.kind == "collision"]
    assert collisions, report.problems
    first = min(collisions, key=lambda p: p.waypoint)
    assert "probe" in first.pair and first.pair[0] in ("suction_cup", "gripper_body")
    assert "×" in first.detail and "mm deep" in first.detail
    assert first.waypoint == first_below(0.0)
    assert first.waypoint <= k <= max(p.last_waypoint for p in collisions)
    # the near miss before the collision is folded into it: where the clearance was first broken
    near = first_below(cell.limits.clearance)
    assert near < first.waypoint and f"inside the clearance from waypoint {near}" in first.detail
    assert not [p for p in report.problems if p.kind == "clearance" and "probe" in p.pair]
    assert report.min_clearance_m < 0 and "probe" in report.min_clearance_pair


def _two_point(cell, q0, q1, move="movej", v=1.0):
    q = np.vstack([q0, q1]).astype(float)
    T = kin.fk_tcp(cell.model, q, cell.tool.tcp)
    return Program(poses=T, q=q, moves=("movej", move), v=np.array([1.0, v]), a=np.array([1.0, 1.0]),
                   states=np.zeros(2), tcp=np.asarray(cell.tool.tcp))


def test_joint_limit_case(ur5e):
    home = np.array(ur5e.robot.home)
    q1 = home.copy()
    q1[5] += 6.6  # wrist 3 past +2 pi
    report, _ = check_program(_two_point(ur5e, home, q1), ur5e)
    lim = [p for p in report.problems if p.kind == "joint_limit"]
    assert len(lim) == 1 and lim[0].subject == "wrist_3" and lim[0].waypoint == 1
    assert lim[0].value == pytest.approx(q1[5])
    assert "wrist_3" in lim[0].detail and "outside" in lim[0].detail


def test_singular_case_wrist_aligned(ur5e):
    home = np.array(ur5e.robot.home)
    q1 = home.copy()
    q1[4] = 0.01  # wrist 2 at 0.6 deg: wrist 1 and wrist 3 axes aligned
    report, _ = check_program(_two_point(ur5e, home, q1), ur5e)
    sing = [p for p in report.problems if p.kind == "singular"]
    assert [p.subject for p in sing] == ["wrist"]
    # the move turns q5 through the interpolation steps toward 0.01 rad: the worst is at most that
    assert sing[0].waypoint == 1 and sing[0].value <= np.sin(0.01) + 1e-12
    assert "q5" in sing[0].detail
    assert not report.ok


def test_too_fast_joint_move_on_ur10e(ur10e):
    home = np.array(ur10e.robot.home)
    q1 = home.copy()
    q1[0] += 0.5
    ok, _ = check_program(_two_point(ur10e, home, q1, v=2.0), ur10e)  # 115 deg/s: within 120
    assert ok.ok, ok.problems
    report, _ = check_program(_two_point(ur10e, home, q1, v=2.5), ur10e)  # 143 deg/s on the base
    assert [(p.kind, p.subject) for p in report.problems] == [("speed", "shoulder_pan")]
    limit = min(ur10e.limits.joint_speed[0], ur10e.model.joint_speed_max[0])
    assert report.problems[0].value == pytest.approx(2.5 / limit)


def test_too_fast_linear_move_at_an_allowed_tcp_speed(ur10e):
    """A movel at 0.25 m/s (the cell's TCP limit) passing 0.18 m from the base axis turns the base
    faster than the UR10e's 120 deg/s; the same move on a slower TCP speed passes."""
    m, tcp = ur10e.model, ur10e.tool.tcp
    P0 = kin.fk_tcp(m, ur10e.robot.home, tcp)
    P1 = P0.copy()
    P0[:3, 3], P1[:3, 3] = [-0.3, -0.18, 0.3], [0.3, -0.18, 0.3]
    q0 = kin.select_nearest(kin.ik(m, P0, tcp), ur10e.robot.home, model=m)
    q1 = q0.copy()
    for t in np.linspace(0, 1, 400)[1:]:  # follow the line to find the joints it arrives with
        P = P0.copy()
        P[:3, 3] = (1 - t) * P0[:3, 3] + t * P1[:3, 3]
        q1 = kin.select_nearest(kin.ik(m, P, tcp), q1, model=m)
    prog = Program(poses=np.stack([P0, P1]), q=np.vstack([q0, q1]), moves=("movej", "movel"),
                   v=np.array([1.0, 0.25]), a=np.array([1.0, 1.0]), states=np.zeros(2), tcp=tcp)
    report, _ = check_program(prog, ur10e)
    assert [(p.kind, p.subject, p.waypoint) for p in report.problems] == [("speed", "shoulder_pan", 1)]
    assert 120 < report.problems[0].value * 120 < 135
    slow = Program(poses=prog.poses, q=prog.q, moves=prog.moves, v=np.array([1.0, 0.2]), a=prog.a,
                   states=prog.states, tcp=tcp)
    assert check_program(slow, ur10e)[0].ok


def test_unreachable_waypoints(ur5e):
    prog = sweep_program(ur5e, 40, height=0.12)
    far = prog.poses.copy()
    far[20, :3, 3] += [0.0, 0.0, 2.0]  # 2 m up: out of reach, stored joints do not match
    q = prog.q.copy()
    q[30] = np.nan  # no joints stored
    bad = Program(poses=far, q=q, moves=prog.moves, v=prog.v, a=prog.a, states=prog.states, tcp=prog.tcp)
    report, _ = check_program(bad, ur5e)
    un = [p for p in report.problems if p.kind == "unreachable" and p.subject == "pose"]
    assert [p.waypoint for p in un] == [20, 30]
    # the linear move into the unreachable pose leaves the workspace on the way
    assert any(p.subject == "workspace" and p.waypoint == 20 for p in report.problems)
    assert "2000.000 mm" in un[0].detail
    assert "no joint solution stored" in un[1].detail


def test_speed_and_acceleration_above_the_cell_limits(ur5e):
    prog = sweep_program(ur5e, 20, height=0.12, v=0.3)  # the cell allows 0.25 m/s
    report, _ = check_program(prog, ur5e)
    tcp = [p for p in report.problems if p.subject == "tcp_speed"]
    assert len(tcp) == 1 and tcp[0].kind == "speed" and tcp[0].waypoint == 0 and tcp[0].last_waypoint == 19


def test_fold_progress_gives_inserted_points_their_fractional_state():
    from sim.check import fold_progress

    # home, approach, grip (state 0), two inserted points, fold to state 1, release at state 2
    states = np.array([0, 0, 0, 0, 0, 1, 2], dtype=float)
    ops = ("home", "approach", "grip", "fold", "fold", "fold", "release")
    x = np.array([9.0, 5.0, 0.0, 0.1, 0.3, 0.4, 0.8])  # TCP travel along x
    P = np.column_stack([x, np.zeros(7), np.zeros(7)])
    out = fold_progress(states, ops, P)
    np.testing.assert_allclose(out, [0, 0, 0, 0.25, 0.75, 1, 2])
    # nothing inserted: unchanged
    np.testing.assert_array_equal(fold_progress(np.array([0.0, 1.0, 2.0]), ("grip", "fold", "release"),
                                                P[:3]), [0, 1, 2])


def test_check_toolpath_entry_point_takes_a_toolpath(ur5e, tmp_path):
    from robot.toolpath import Toolpath
    from sim.check import check_toolpath
    from sim.programs import toolpath_from_program

    tp = toolpath_from_program(sweep_program(ur5e, 60, height=0.12), ur5e)
    report = check_toolpath(tp, ur5e)
    assert report.ok and report.toolpath_sha256 == tp.sha256 == Toolpath.from_json(tp.to_json()).sha256
    tp.save(tmp_path / "p.json")
    assert check_toolpath(tmp_path / "p.json", ur5e).toolpath_sha256 == tp.sha256


def test_linear_move_arriving_on_another_branch_is_unreachable_not_a_speed_problem(ur5e):
    m, tcp = ur5e.model, ur5e.tool.tcp
    prog = sweep_program(ur5e, 2, height=0.12)
    q0 = prog.q[0]
    P1 = prog.poses[0].copy()
    P1[:3, 3] += [0.02, 0.0, 0.0]
    S = kin.ik(m, P1, tcp)
    other = [q for q in S if (kin.branch_signs(m, q) != kin.branch_signs(m, q0)).any()]
    q1 = kin.unwrap_near(other[0], q0, m)
    bad = Program(poses=np.stack([prog.poses[0], P1]), q=np.vstack([q0, q1]), moves=("movej", "movel"),
                  v=np.array([1.0, 0.1]), a=np.array([1.0, 1.0]), states=np.zeros(2), tcp=tcp)
    report, _ = check_program(bad, ur5e)
    arrival = [p for p in report.problems if p.subject == "arrival"]
    assert len(arrival) == 1 and arrival[0].kind == "unreachable" and arrival[0].waypoint == 1
    assert kin.branch_label(m, q1) in arrival[0].detail
    assert not [p for p in report.problems if p.kind == "speed"]
