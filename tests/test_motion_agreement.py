"""The one UR motion model (`robot.ur_motion`) as its three users see it, on the same programs: the
planner's cycle time (`robot.motion.toolpath_cycle_time`), the checker's interpolation of the path
actually driven (`sim.interpolate`, blends included) and the controller stand-in's executed motion
(its planner and its arm object stepped in-process at the controller period, as the tick does).

Tolerances, stated: the stand-in executes each run in whole controller periods, so its execution
time exceeds the model's by at most one period (2 ms) per run; the checker's TCP samples and the
stand-in's TCP at the same run time agree to 0.1 mm (the stand-in's IK knots and cubic spline, and
linear interpolation between its 2 ms samples)."""
from dataclasses import replace

import numpy as np
import pytest

from _ursim import CELL, demo_toolpath
from robot import kinematics as K
from robot import ur_motion as U
from robot.cell import load_cell, matrix_to_pose, pose_to_matrix
from robot.motion import toolpath_cycle_time
from robot.toolpath import Toolpath
from sim.interpolate import interpolate_program
from sim.toolpath_program import program_from_toolpath
from sim.ursim.arm import Arm
from sim.ursim.motion import Waypoint, plan_moves

DT = 0.002  # the e-Series controller period
TCP_TOL_M = 1e-4


@pytest.fixture(scope="module")
def cell():
    return load_cell(CELL)


def _waypoints(tp, first: int, last: int) -> list[Waypoint]:
    """The moves first+1 .. last as the stand-in receives them from fabkit's URScript."""
    out = []
    for w in tp.waypoints[first + 1:last + 1]:
        out.append(Waypoint(w.move, w.v, w.a, w.r, q=tuple(w.q) if w.move == "movej" else None,
                            pose=tuple(w.pose) if w.move == "movel" else None))
    return out


def _execute(cell, q0, wps, fraction: float = 1.0, bound: float = U.JOINT_ACCEL_MAX):
    """The stand-in's arm executing `wps` from `q0`: (execution time s, joints per period)."""
    traj = plan_moves(cell.model, cell.tool.tcp, q0, wps, DT, joint_accel_max=bound)
    arm = Arm(q0, cell.model.joint_speed_max, bound)
    arm.run(traj)
    qs, ticks = [arm.q.copy()], 0
    while arm.mode != "idle":
        arm.step(DT, fraction)
        qs.append(arm.q.copy())
        ticks += 1
        assert ticks < 10 ** 6
    return ticks * DT, np.array(qs)


def _agree(cell, tp):
    """Planner vs stand-in time, checker vs stand-in TCP per run; returns the numbers compared."""
    prog = replace(program_from_toolpath(tp, cell), dwell=None)
    dense = interpolate_program(cell.model, prog)
    assert dense.events == ()
    planned = toolpath_cycle_time(tp).motion
    assert dense.t[-1] == pytest.approx(planned, abs=1e-6)  # the checker times the path as the planner does
    runs = U.run_bounds([w.move for w in tp.waypoints], [w.r for w in tp.waypoints])
    executed, worst = 0.0, 0.0
    T_check = K.fk_tcp(cell.model, dense.q, cell.tool.tcp)[:, :3, 3]
    for first, last in runs:
        q0 = np.asarray(tp.waypoints[first].q)
        t_run, qs = _execute(cell, q0, _waypoints(tp, first, last))
        executed += t_run
        assert np.abs(qs[-1] - tp.waypoints[last].q).max() < 1e-9  # ends exactly on the stored joints
        # the checker's samples inside this run against the stand-in's TCP at the same run time
        t0 = dense.t[np.flatnonzero(dense.at_waypoint & (dense.waypoint == first))[0]]
        inside = np.flatnonzero((dense.waypoint > first) & (dense.waypoint <= last))
        T_run = K.fk_tcp(cell.model, qs, cell.tool.tcp)[:, :3, 3]
        x = (dense.t[inside] - t0) / DT
        k = np.clip(np.floor(x).astype(int), 0, len(qs) - 2)
        f = np.clip(x - k, 0.0, 1.0)[:, None]
        stand_in = T_run[k] * (1 - f) + T_run[k + 1] * f
        worst = max(worst, float(np.linalg.norm(stand_in - T_check[inside], axis=1).max()))
    return planned, executed, worst, len(runs), dense, prog


def test_demo_program_planner_checker_and_stand_in_agree(cell):
    planned, executed, worst, n_runs, dense, _ = _agree(cell, demo_toolpath())
    print(f"\ndemo: planner {planned:.4f} s, stand-in {executed:.4f} s ({n_runs} runs), "
          f"checker vs stand-in TCP {worst * 1e6:.1f} um")
    assert 0.0 <= executed - planned <= n_runs * DT + 1e-9
    assert worst < TCP_TOL_M


def _blended_square(cell, r=0.02):
    """A blended movel program in the bench cell: home, then five corners of a tilted square
    (the tool turning 0.3 rad along it) with blends of `r`, the last one a stop."""
    home = np.asarray(cell.robot.home, dtype=np.float64)
    T0 = K.fk_tcp(cell.model, home, cell.tool.tcp)
    p0 = matrix_to_pose(T0)
    offsets = [(0.0, 0.0, -0.05), (0.12, 0.0, -0.05), (0.12, 0.10, -0.03), (0.0, 0.10, -0.03), (0.0, 0.02, -0.05),
               (0.06, 0.02, -0.06)]
    wps, q_prev = [{"pose": list(p0), "q": list(home), "move": "movej", "v": 1.0, "a": 1.4, "r": 0.0, "state": 0,
                    "op": "home"}], home
    for i, d in enumerate(offsets):
        T = pose_to_matrix(p0 + np.r_[d, 0, 0, 0])
        c, s = np.cos(0.05 * i), np.sin(0.05 * i)
        T[:3, :3] = T[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        q = K.select_nearest(K.ik(cell.model, T, cell.tool.tcp), q_prev, model=cell.model)
        q_prev = q
        inner = 0 < i < len(offsets) - 1
        wps.append({"pose": list(matrix_to_pose(T)), "q": list(q), "move": "movel", "v": 0.25, "a": 1.2,
                    "r": r if inner else 0.0, "state": 0, "op": "fold"})
    return Toolpath(robot=cell.model.name, cell=cell.name, tcp=tuple(matrix_to_pose(cell.tool.tcp)),
                    source={"test": "square"}, waypoints=tuple(wps), extra={}, cell_sha256=cell.sha256)


def test_blended_movel_program_agrees_and_the_checker_checks_the_blended_path(cell):
    tp = _blended_square(cell)
    planned, executed, worst, n_runs, dense, prog = _agree(cell, tp)
    print(f"\nblended square: planner {planned:.4f} s, stand-in {executed:.4f} s, TCP {worst * 1e6:.1f} um")
    assert 0.0 <= executed - planned <= n_runs * DT + 1e-9
    assert worst < TCP_TOL_M
    # the checked path cuts every blended corner: nearest approach between 0 and r, never the corner
    T = K.fk_tcp(cell.model, dense.q, cell.tool.tcp)[:, :3, 3]
    for i in range(2, len(prog) - 1):
        gap = np.linalg.norm(T - prog.poses[i][:3, 3], axis=1).min()
        assert 0.002 < gap < prog.r[i], (i, gap)
    # blends are faster than stopping: the same corners with r = 0 take longer
    stopped = toolpath_cycle_time(_blended_square(cell, r=0.0)).motion
    assert stopped > planned + 0.1


def test_speed_slider_time_scales_the_arm_and_keeps_the_path(cell):
    """At 50 % the stand-in's arm takes twice as long (to one period per run) on the same joints."""
    tp = demo_toolpath()
    wps = _waypoints(tp, 0, len(tp.waypoints) - 1)
    q0 = np.asarray(tp.waypoints[0].q)
    full, q_full = _execute(cell, q0, wps)
    half, q_half = _execute(cell, q0, wps, fraction=0.5)
    assert half / full == pytest.approx(2.0, abs=2 * DT / full)
    assert np.abs(q_half[-1] - q_full[-1]).max() < 1e-12
    # the half-speed path is the full-speed one sampled twice as densely
    assert np.abs(q_half[::2][:len(q_full)] - q_full[:len(q_half[::2])]).max() < 1e-9


def _fast_movej(cell, held_kg: float | None):
    """Home, approach, a quick 0.6 rad base swing (a = 35 rad/s^2) holding a part, and back; with a
    payload record (tool 0.5 kg, tool + part `held_kg`) unless `held_kg` is None."""
    home = np.asarray(cell.robot.home, dtype=np.float64)
    swing = home + np.array([0.6, 0.1, -0.1, 0.0, 0.0, 0.0])
    poses = [matrix_to_pose(K.fk_tcp(cell.model, q, cell.tool.tcp)) for q in (home, home, swing, home)]
    ops = ["home", "grip", "release", "home"]
    qs = [home, home, swing, home]
    wps = tuple({"pose": list(p), "q": list(q), "move": "movej", "v": 3.0, "a": 35.0, "r": 0.0, "state": 0, "op": o}
                for p, q, o in zip(poses, qs, ops))
    extra = {}
    if held_kg is not None:
        extra["payload"] = {"tool_mass_kg": 0.5, "tool_cog_m": [0, 0, 0.05], "panel_mass_kg": held_kg - 0.5,
                            "held_mass_kg": held_kg, "held_cog_m": [0, 0, 0.06]}
    return Toolpath(robot=cell.model.name, cell=cell.name, tcp=tuple(matrix_to_pose(cell.tool.tcp)),
                    source={"test": "payload"}, waypoints=wps, extra=extra, cell_sha256=cell.sha256)


def test_heavier_payload_takes_longer_as_the_model_predicts_and_ends_on_the_same_pose(cell):
    from robot.loads import arm_rating

    rated = arm_rating(cell.model.name).payload
    light, heavy = _fast_movej(cell, 1.0), _fast_movej(cell, 4.5)
    t_light, t_heavy = toolpath_cycle_time(light).motion, toolpath_cycle_time(heavy).motion
    # the swing under 4.5 kg: a = 40 (1 - 0.5 * 4.5 / 5) = 22 rad/s^2 instead of 35
    a_heavy = U.joint_accel_bound(4.5, rated)
    assert a_heavy == pytest.approx(U.JOINT_ACCEL_MAX * (1 - U.PAYLOAD_ACCEL_DERATE * 4.5 / rated))
    swing = 0.6
    expected = U.time_law([swing], [3.0], [a_heavy]).duration - U.time_law([swing], [3.0], [35.0]).duration
    # only the swing holds the part (the way back after the release carries the 0.5 kg tool alone,
    # whose bound 38 rad/s^2 leaves a = 35 as programmed), and 1 kg leaves 36 > 35
    assert t_heavy - t_light == pytest.approx(expected, rel=1e-9)
    assert t_heavy - t_light > 20 * DT  # measurable: 50 ms, 25 controller periods
    # the stand-in with each payload's bound on the moves holding it
    q0 = np.asarray(light.waypoints[1].q)
    ends = []
    for tp, held in ((light, 1.0), (heavy, 4.5)):
        t_exec, qs = _execute(cell, q0, _waypoints(tp, 1, 2), bound=U.joint_accel_bound(held, rated))
        planned = toolpath_cycle_time(tp).segments[1]
        assert 0.0 <= t_exec - planned <= DT + 1e-9
        ends.append(qs[-1])
    assert np.abs(ends[0] - ends[1]).max() == 0.0
    # the checker's interpolation uses the same bound
    dense = interpolate_program(cell.model, program_from_toolpath(heavy, cell))
    assert dense.t[-1] == pytest.approx(toolpath_cycle_time(heavy).total, abs=1e-6)


def test_payload_over_the_rating_is_refused(cell):
    from fabkit.errors import InputError

    with pytest.raises(U.PayloadError, match="exceeds the arm's rated payload"):
        toolpath_cycle_time(_fast_movej(cell, 5.5))
    with pytest.raises(InputError, match="rated payload"):
        program_from_toolpath(_fast_movej(cell, 5.5), cell)


def test_overlapping_blends_are_a_check_problem_as_on_the_controller(cell):
    tp = _blended_square(cell, r=0.07)  # 70 mm blends on 100-120 mm sides: neighbours overlap
    prog = program_from_toolpath(tp, cell)
    dense = interpolate_program(cell.model, prog)
    assert [(e.kind, e.subject) for e in dense.events] == [("unreachable", "blend")]
    assert "blends cannot overlap" in dense.events[0].detail
    with pytest.raises(U.BlendOverlap):
        toolpath_cycle_time(tp)
