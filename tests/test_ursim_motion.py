"""The stand-in's motion planner against known answers: trapezoid durations, straight lines, exact
ends, blends that stay within their radius, overlap errors, progress markers; and its URScript
parser on the statements fabkit writes and on text a controller would refuse."""
import numpy as np
import pytest

from robot import kinematics as K
from sim.ursim.motion import PlanError, Waypoint, matrix_to_pose, plan_moves
from sim.ursim.urscript import ScriptError, parse_program, path_waypoints, parse_statements

M = K.get_model("ur5e")
HOME = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])
Q0 = np.array([0.1, -1.4, 1.6, -1.8, -1.5, 0.2])
DT = 0.002


def test_movej_trapezoid_duration_and_exact_end():
    d, v, a = 1.0, 0.5, 1.0  # leading joint moves 1 rad: ramp 0.5 s, cruise 0.75 s, ramp 0.5 s
    target = Q0 + np.array([d, 0.3, -0.2, 0.0, 0.1, -0.5])
    tr = plan_moves(M, np.eye(4), Q0, [Waypoint("movej", v, a, q=tuple(target))], DT)
    assert tr.duration == pytest.approx(d / v + v / a, abs=DT)
    assert np.array_equal(tr.q[-1], target)
    qd = np.abs(np.diff(tr.q, axis=0)) / DT
    assert qd[:, 0].max() == pytest.approx(v, rel=1e-3)
    # the other joints are scaled so that all arrive together (linear in joint space)
    moving = np.flatnonzero(target != Q0)
    frac = (tr.q[:, moving] - Q0[moving]) / (target - Q0)[moving]
    assert np.allclose(frac, frac[:, :1], atol=1e-9)


def test_movej_triangle_profile():
    d, v, a = 0.2, 1.0, 2.0  # never reaches v: t = 2 sqrt(d / a)
    tr = plan_moves(M, np.eye(4), Q0, [Waypoint("movej", v, a, q=tuple(Q0 + [d, 0, 0, 0, 0, 0]))], DT)
    assert tr.duration == pytest.approx(2 * np.sqrt(d / a), abs=DT)


def test_movel_is_straight_and_ends_on_the_pose():
    tcp = np.eye(4)
    tcp[2, 3] = 0.13
    start = matrix_to_pose(K.fk_tcp(M, Q0, tcp))
    target = start + np.array([0.12, -0.05, 0.04, 0.0, 0.0, 0.0])
    tr = plan_moves(M, tcp, Q0, [Waypoint("movel", 0.25, 1.2, pose=tuple(target))], DT)
    P = K.fk_tcp(M, tr.q, tcp)[:, :3, 3]
    u = (target[:3] - start[:3]) / np.linalg.norm(target[:3] - start[:3])
    rel = P - start[:3]
    off = np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)
    assert off.max() < 2e-6  # cubic spline between IK knots 4 mm apart
    assert np.abs(matrix_to_pose(K.fk_tcp(M, tr.q[-1], tcp)) - target).max() < 1e-12
    speed = np.linalg.norm(np.diff(P, axis=0), axis=1) / DT
    assert speed.max() == pytest.approx(0.25, rel=1e-3)
    L = np.linalg.norm(target[:3] - start[:3])
    assert tr.duration == pytest.approx(L / 0.25 + 0.25 / 1.2, abs=DT)


def test_blended_path_stays_inside_blend_zones_and_reports_progress():
    tcp = np.eye(4)
    start = matrix_to_pose(K.fk(M, HOME))
    corners = [start + np.array([0.1, 0, 0, 0, 0, 0]), start + np.array([0.1, 0.1, 0, 0, 0, 0]),
               start + np.array([0.0, 0.1, 0, 0, 0, 0])]
    r = 0.02
    wps = [Waypoint("movel", 0.2, 1.0, r=r, pose=tuple(corners[0]), progress=0),
           Waypoint("movel", 0.2, 1.0, r=r, pose=tuple(corners[1]), progress=1),
           Waypoint("movel", 0.2, 1.0, r=0.0, pose=tuple(corners[2]), progress=2)]
    tr = plan_moves(M, tcp, HOME, wps, DT)
    P = K.fk(M, tr.q)[:, :3, 3]
    for c in corners[:2]:  # a blend never reaches its corner but passes within r of it
        dist = np.linalg.norm(P - c[:3], axis=1).min()
        assert 0.003 < dist < r
    assert np.linalg.norm(P[-1] - corners[2][:3]) < 1e-12
    # the arm does not stop inside a blend: TCP speed stays above half the cruise speed there
    k = np.argmin(np.linalg.norm(P - corners[0][:3], axis=1))
    assert np.linalg.norm(P[k + 1] - P[k - 1]) / (2 * DT) > 0.1
    idx = [i for i, p in tr.markers]
    assert [p for i, p in tr.markers] == [0, 1, 2] and idx == sorted(idx)
    # progress 1 is written where the blend around corner 0 begins, r before the corner
    assert np.linalg.norm(P[tr.markers[1][0]] - corners[0][:3]) == pytest.approx(r, abs=2e-3)


def test_overlapping_blends_are_a_runtime_error():
    start = matrix_to_pose(K.fk(M, HOME))
    wps = [Waypoint("movel", 0.2, 1.0, r=0.03, pose=tuple(start + [0.05, 0, 0, 0, 0, 0])),
           Waypoint("movel", 0.2, 1.0, r=0.03, pose=tuple(start + [0.05, 0.04, 0, 0, 0, 0])),
           Waypoint("movel", 0.2, 1.0, r=0.0, pose=tuple(start + [0.1, 0.04, 0, 0, 0, 0]))]
    with pytest.raises(PlanError, match="overlap"):
        plan_moves(M, np.eye(4), HOME, wps, DT)


def test_unreachable_movel_is_a_runtime_error():
    start = matrix_to_pose(K.fk(M, HOME))
    with pytest.raises(PlanError, match="no solution"):
        plan_moves(M, np.eye(4), HOME, [Waypoint("movel", 0.25, 1.2, pose=tuple(start + [2.0, 0, 0, 0, 0, 0]))], DT)


def test_fabkit_program_parses():
    text = """def fold_panel():
  # gripper TCP
  set_tcp(p[0.0, 0.0, 0.13, 0.0, 0.0, 0.0])
  movej([0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0], a=1.4, v=1.05, r=0)
  movel(p[-0.45, -0.13, 0.35, 2.2214, 2.2214, 0.0], a=1.2, v=0.25, r=0.005)
  set_tool_digital_out(0, True)
  set_standard_digital_out(3, False)
  write_output_integer_register(20, 7)
  sleep(0.5)
  textmsg("fold state 1 # of 3")
end
"""
    name, sts = parse_program(text)
    assert name == "fold_panel"
    assert [s.name for s in sts] == ["set_tcp", "movej", "movel", "set_tool_digital_out", "set_standard_digital_out",
                                     "write_output_integer_register", "sleep", "textmsg"]
    assert sts[2].is_pose and not sts[1].is_pose and sts[2].kwargs == {"a": 1.2, "v": 0.25, "r": 0.005}


@pytest.mark.parametrize("body, match", [
    ("  x = 1", "unsupported statement"),
    ("  while True:\n    sync()\n  end", "nested blocks"),
    ("  popup(\"hi\")", "unknown or unsupported function"),
    ("  movel(p[0, 0, 0.3, 0, 0], a=1.2, v=0.25)", "6-vector"),
    ("  movel(p[0, 0, 0.3, 0, 0, 0], a=1.2, v=0.25, t=2)", "t= is not supported"),
    ("  set_tool_digital_out(0)", "takes 2 arguments"),
    ("  movej([0, 0, 0, 0, 0, 0], a=1.4, v=undefined_var)", "cannot evaluate"),
])
def test_unsupported_script_is_rejected_with_its_line(body, match):
    with pytest.raises(ScriptError, match=match) as err:
        parse_program(f"def prog():\n{body}\nend\n")
    assert "line 2" in str(err.value)


def test_program_without_end_is_rejected():
    with pytest.raises(ScriptError, match="no closing 'end'"):
        parse_program("def prog():\n  sleep(1)\n")


def test_injected_path_as_ur_rtde_prints_it():
    rtde_control = pytest.importorskip("rtde_control")
    path = rtde_control.Path()
    E = rtde_control.PathEntry
    path.addEntry(E(E.MoveL, E.PositionTcpPose, [0.1234567, -0.5, 0.3, 3.14159265, 0.01, 1e-7, 0.25, 1.2, 0.005]))
    path.addEntry(E(E.MoveJ, E.PositionJoints, [0, -1.57, 1.57, -1.57, -1.57, 0, 1.05, 1.4, 0.0]))
    code = path.toScriptCode()
    wps = path_waypoints(parse_statements(list(enumerate(code.split("\n"), start=1))))
    assert [w.kind for w in wps] == ["movel", "movej"]
    assert wps[0].pose == (0.123457, -0.5, 0.3, 3.14159, 0.01, 1e-7)  # 6 significant digits
    assert (wps[0].v, wps[0].a, wps[0].r, wps[0].progress) == (0.25, 1.2, 0.005, 0)
    assert wps[1].q == (0.0, -1.57, 1.57, -1.57, -1.57, 0.0) and wps[1].progress == 1


def test_fault_option_parsing():
    from sim.ursim.admin import parse_fault_option

    f = parse_fault_option("protective_stop@progress=20:bumped the fixture")
    assert f["kind"] == "protective_stop" and f["at_progress"] == 20 and f["arg"] == "bumped the fixture"
    f = parse_fault_option("stall@t=2.5:10")
    assert f["kind"] == "stall" and f["arg"] == "10" and "at_time" in f
    with pytest.raises(ValueError, match="unknown fault"):
        parse_fault_option("gremlins")
    with pytest.raises(ValueError, match="bad fault trigger"):
        parse_fault_option("estop@sometime")


def test_joint_accelerations_stay_within_the_bound_by_slowing_the_run():
    """A fast blended movel square (1 m/s, 10 m/s^2) would need more joint acceleration than the
    bound: the stand-in slows the whole run until its executed joint accelerations fit."""
    start = matrix_to_pose(K.fk(M, HOME))
    corners = [(0.15, 0, 0), (0.15, 0.15, 0), (0.0, 0.15, 0)]
    wps = [Waypoint("movel", 1.0, 10.0, 0.03 if i < 2 else 0.0, pose=tuple(start + np.r_[c, 0, 0, 0]))
           for i, c in enumerate(corners)]
    durations = []
    for bound in (40.0, 20.0, 8.0):
        tr = plan_moves(M, np.eye(4), HOME, wps, DT, joint_accel_max=bound)
        peak = np.abs(np.diff(tr.q, 2, axis=0)).max() / DT ** 2
        assert tr.stretch > 1.0 and peak <= bound
        assert np.abs(matrix_to_pose(K.fk(M, tr.q[-1])) - (start + np.r_[corners[-1], 0, 0, 0])).max() < 1e-9
        durations.append(tr.duration)
    assert durations[0] < durations[1] < durations[2]
