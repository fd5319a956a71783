"""The unmodified ur_rtde 1.6.5 RTDEControlInterface drives the stand-in (or, with FABKIT_UR_HOST,
a real URSim / robot): moveJ, moveL and a 50-waypoint blended moveL(path) end on target, IK and FK
agree with robot.kinematics, a second control client gets IN_USE, protective stops behave as
ur_rtde documents. The stand-in runs in its own process on this module's loopback address."""
import time

import numpy as np
import pytest

from _ursim import external_host, standin_fixture
from robot import kinematics as K
from sim.ursim.motion import matrix_to_pose, pose_to_matrix

pytestmark = pytest.mark.network
needs_standin = pytest.mark.skipif(external_host() is not None, reason="fault injection needs the stand-in")


standin = standin_fixture(unlock_delay="0.5", external_ok=True)


@pytest.fixture(scope="module")
def host(standin):
    return external_host() or standin.host


@pytest.fixture(scope="module")
def clients(host):
    import rtde_control
    import rtde_receive

    ctrl = rtde_control.RTDEControlInterface(host, -1.0, rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT,
                                             50002, -1)
    recv = rtde_receive.RTDEReceiveInterface(host)
    yield ctrl, recv
    ctrl.stopScript()
    ctrl.disconnect()
    recv.disconnect()


def _q(recv):
    return np.array(recv.getActualQ())


def test_movej_movel_end_on_target(clients):
    ctrl, recv = clients
    q0 = _q(recv)
    target = q0 + np.array([0.15, -0.1, 0.12, -0.05, 0.1, 0.2])
    assert ctrl.moveJ(target.tolist(), 1.0, 1.4)
    assert np.abs(_q(recv) - target).max() < 1e-4
    p0 = np.array(recv.getActualTCPPose())
    goal = p0 + np.array([0.04, -0.03, 0.05, 0.0, 0.0, 0.0])
    assert ctrl.moveL(goal.tolist(), 0.25, 1.2)
    q_goal = np.array(ctrl.getInverseKinematics(goal.tolist(), target.tolist()))
    assert np.abs(_q(recv) - q_goal).max() < 1e-4
    assert np.abs(np.array(recv.getActualTCPPose())[:3] - goal[:3]).max() < 1e-6
    assert ctrl.isSteady()


def _soon(cond, timeout: float = 0.5) -> bool:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


def test_movej_ik_movel_fk_and_stops(clients):
    ctrl, recv = clients
    q0 = _q(recv)
    p0 = np.array(recv.getActualTCPPose())
    goal = p0 + np.array([-0.03, 0.04, 0.02, 0, 0, 0])
    assert ctrl.moveJ_IK(goal.tolist(), 1.0, 1.4)  # joint move to the IK solution nearest q0
    # the receive stream may trail the control stream by a few periods on a loaded machine
    assert _soon(lambda: np.abs(np.array(recv.getActualTCPPose()) - goal).max() < 1e-9)
    assert ctrl.moveL_FK(q0.tolist(), 0.25, 1.2)  # straight TCP line to FK(q0)
    assert _soon(lambda: np.abs(_q(recv) - q0).max() < 1e-6)
    # an asynchronous move stopped with stopJ / stopL decelerates and stays put
    for stop in (lambda: ctrl.stopJ(2.0, False), lambda: ctrl.stopL(5.0, False)):
        assert ctrl.moveJ((q0 + 0.6).tolist(), 0.5, 1.0, True)
        time.sleep(0.4)
        stop()  # returns None in the Python binding; blocks until the arm has stopped
        assert ctrl.getAsyncOperationProgress() < 0 and ctrl.isSteady()
        q_stop = _q(recv)
        assert 0.01 < np.abs(q_stop - q0).max() < 0.5
        time.sleep(0.1)
        assert np.abs(_q(recv) - q_stop).max() < 1e-12
        assert ctrl.moveJ(q0.tolist())


def test_fifty_waypoint_blended_path(clients):
    ctrl, recv = clients
    p0 = np.array(recv.getActualTCPPose())
    path = []
    for i in range(50):
        th = 0.9 * 2 * np.pi * i / 49
        p = p0 + np.array([0.08 * np.sin(th), 0.08 * (1 - np.cos(th)), 0.02 * np.sin(th), 0, 0, 0])
        path.append(p.tolist() + [0.25, 1.2, 0.004 if 0 < i < 49 else 0.0])
    assert ctrl.moveL(path)
    target = np.array(ctrl.getInverseKinematics(path[-1][:6]))
    assert np.abs(_q(recv) - target).max() < 1e-4


def test_joint_path_and_mixed_move_path(clients):
    import rtde_control

    ctrl, recv = clients
    q0 = _q(recv)
    qs = [q0 + np.array([0.1, -0.05, 0.05, 0.0, 0.05, 0.1]) * k for k in (1, 2, 3)]
    assert ctrl.moveJ([list(q) + [1.0, 1.4, 0.01 if k < 2 else 0.0] for k, q in enumerate(qs)])
    assert np.abs(_q(recv) - qs[-1]).max() < 1e-4  # 6 printed digits: ~1e-6 rad
    p = np.array(recv.getActualTCPPose())
    path = rtde_control.Path()
    E = rtde_control.PathEntry
    path.addEntry(E(E.MoveL, E.PositionTcpPose, list(p + [0.03, 0, 0, 0, 0, 0]) + [0.25, 1.2, 0.0]))
    path.addEntry(E(E.MoveJ, E.PositionJoints, list(q0) + [1.0, 1.4, 0.0]))
    assert ctrl.movePath(path, False)
    assert np.abs(_q(recv) - q0).max() < 1e-4


def test_async_path_reports_progress(clients):
    ctrl, recv = clients
    p0 = np.array(recv.getActualTCPPose())
    path = [(p0 + np.array([0.01 * i, 0.005 * i, 0, 0, 0, 0])).tolist() + [0.1, 1.0, 0.002 if 0 < i < 9 else 0]
            for i in range(10)]
    assert ctrl.moveL(path, True)
    seen = set()
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        p = ctrl.getAsyncOperationProgress()
        if p < 0 and seen:
            break
        if p >= 0:
            seen.add(p)
        time.sleep(0.005)
    assert len(seen) >= 5 and max(seen) == 9
    end = np.array(path[-1][:3])
    deadline = time.monotonic() + 2  # the receive stream may lag the control stream by a few periods
    while np.abs(np.array(recv.getActualTCPPose())[:3] - end).max() > 1e-5 and time.monotonic() < deadline:
        time.sleep(0.005)
    assert np.abs(np.array(recv.getActualTCPPose())[:3] - end).max() < 1e-5


def test_ik_and_fk_agree_with_robot_kinematics(clients, rng):
    ctrl, recv = clients
    model = K.get_model("ur5e")
    tcp_pose = [0.01, -0.02, 0.13, 0.1, -0.05, 0.2]
    tcp = pose_to_matrix(tcp_pose)
    assert ctrl.setTcp([0.0] * 6)  # the IK below is of the flange (an installation may have a TCP set)
    for _ in range(3):
        q = _q(recv) + rng.uniform(-0.3, 0.3, 6)
        fk = np.array(ctrl.getForwardKinematics(q.tolist(), tcp_pose))
        ours = matrix_to_pose(K.fk_tcp(model, q, tcp))
        assert np.abs(fk - ours).max() < 1e-9
        qnear = q + rng.uniform(-0.05, 0.05, 6)
        ik = np.array(ctrl.getInverseKinematics(fk.tolist(), qnear.tolist()))
        # the controller's active TCP is the flange here: compare with our IK of the same pose
        ref = K.select_nearest(K.ik(model, pose_to_matrix(fk)), qnear, model=model)
        assert np.abs(ik - ref).max() < 1e-9
    assert ctrl.setTcp(tcp_pose)
    assert np.abs(np.array(ctrl.getTCPOffset()) - tcp_pose).max() < 1e-12
    assert np.abs(np.array(ctrl.getForwardKinematics()) - np.array(recv.getActualTCPPose())).max() < 1e-9
    assert ctrl.setTcp([0.0] * 6)


def test_safety_limit_queries(clients):
    ctrl, recv = clients
    assert ctrl.isJointsWithinSafetyLimits(recv.getActualQ())
    assert not ctrl.isJointsWithinSafetyLimits([0, 0, 4.0, 0, 0, 0])  # elbow beyond +-pi
    assert ctrl.isPoseWithinSafetyLimits(recv.getActualTCPPose())
    assert not ctrl.isPoseWithinSafetyLimits([3.0, 0, 0.3, 0, 3.14, 0])  # out of reach


def test_servoj_speedj_and_stops(clients):
    ctrl, recv = clients
    q0 = _q(recv)
    for k in range(1, 101):  # 0.2 s of servoing toward a target 0.02 rad away
        ctrl.servoJ((q0 + 0.0002 * k).tolist(), 0.5, 0.5, 0.002, 0.1, 300)
        time.sleep(0.002)
    assert ctrl.servoStop()
    assert np.abs(_q(recv) - (q0 + 0.02)).max() < 0.02
    assert ctrl.speedJ([0.1, 0, 0, 0, 0, 0], 1.0, 0.0)
    time.sleep(0.3)
    assert ctrl.speedStop(2.0)
    assert _q(recv)[0] > q0[0] + 0.02
    assert ctrl.isSteady()


def test_second_control_client_gets_in_use(clients, host):
    import rtde_control

    with pytest.raises(RuntimeError, match="already in use"):
        rtde_control.RTDEControlInterface(host, -1.0, rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT, 50002, -1)


@needs_standin
def test_protective_stop_during_move_and_recovery(clients, standin, host):
    import dashboard_client

    ctrl, recv = clients
    q0 = _q(recv)
    assert ctrl.moveJ((q0 + 0.5).tolist(), 0.2, 0.5, True)
    time.sleep(0.3)
    assert standin.admin("protective_stop")["ok"]
    t0 = time.monotonic()
    while not recv.isProtectiveStopped() and time.monotonic() - t0 < 2:
        time.sleep(0.01)
    assert recv.isProtectiveStopped() and recv.getSafetyStatusBits() & (1 << 2)
    assert not ctrl.moveJ(q0.tolist())  # moves fail until the stop is cleared and the script reloaded
    q_stop = _q(recv)
    time.sleep(0.2)
    assert np.array_equal(_q(recv), q_stop)  # the arm stays where it stopped
    d = dashboard_client.DashboardClient(host)
    d.connect()
    time.sleep(0.6)  # this stand-in unlocks after 0.5 s (a controller: 5 s)
    d.unlockProtectiveStop()
    d.closeSafetyPopup()
    d.disconnect()
    assert ctrl.reuploadScript()  # returns once the script is sent, not when it runs
    t0 = time.monotonic()
    while not (ctrl.isProgramRunning() and recv.getSafetyStatusBits() == 1) and time.monotonic() - t0 < 5:
        time.sleep(0.01)
    assert ctrl.moveJ(q0.tolist())
    assert np.abs(_q(recv) - q0).max() < 1e-4
