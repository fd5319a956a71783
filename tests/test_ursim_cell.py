"""The stand-in with a cell: a move into the bench ends in a protective stop from a MuJoCo contact
(safety mode and status bits as a controller reports them), the RTDE watchdog stops a program whose
client goes quiet, and `fabkit ursim` refuses bad options with one line (exit 2)."""
import time

import numpy as np
import pytest

from _ursim import CELL, external_host, standin_fixture
from fabkit.cli import main as fabkit_main

pytestmark = [pytest.mark.network, pytest.mark.skipif(external_host() is not None,
                                                      reason="needs the stand-in")]


standin = standin_fixture("--cell", str(CELL), unlock_delay="0.2")


@pytest.fixture(scope="module")
def clients(standin):
    import rtde_control
    import rtde_receive

    ctrl = rtde_control.RTDEControlInterface(standin.host, -1.0, rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT,
                                             50002, -1)
    recv = rtde_receive.RTDEReceiveInterface(standin.host)
    yield ctrl, recv
    ctrl.disconnect()
    recv.disconnect()


def _wait(cond, timeout=5.0):
    t0 = time.monotonic()
    while not cond() and time.monotonic() - t0 < timeout:
        time.sleep(0.01)
    return cond()


def _recover(ctrl, recv, host):
    """Unlock a protective stop if there is one and make sure the control script runs."""
    import dashboard_client

    if recv.getSafetyMode() == 3:
        d = dashboard_client.DashboardClient(host)
        d.connect()
        time.sleep(0.3)  # this stand-in's unlock delay is 0.2 s
        d.unlockProtectiveStop()
        d.disconnect()
    if not ctrl.isProgramRunning():
        assert ctrl.reuploadScript()
    assert _wait(lambda: ctrl.isProgramRunning() and recv.getSafetyStatusBits() == 1)


@pytest.fixture
def ready(clients, standin):
    _recover(*clients, standin.host)
    return clients


def test_collision_with_the_bench_is_a_protective_stop(standin, ready):
    ctrl, recv = ready
    pose = np.array(recv.getActualTCPPose())
    # the cell's TCP (0.13 m) is active; straight down 0.45 m goes through the bench top
    assert recv.getActualTCPPose()[2] == pytest.approx(standin.state()["tcp_pose"][2])
    target = pose - np.array([0, 0, 0.45, 0, 0, 0])
    assert not ctrl.moveL(target.tolist(), 0.25, 1.2)  # the move fails when the arm stops
    assert _wait(lambda: recv.getSafetyMode() == 3)  # the receive stream may lag the control stream
    assert recv.getSafetyMode() == 3 and recv.getSafetyStatusBits() == (1 << 2) | (1 << 10)
    state = standin.state()
    assert state["safety_mode"] == "PROTECTIVE_STOP" and "collision" in state["last_error"]
    assert "bench" in state["last_error"]
    # stopped at first contact: the suction cup (ending 2 mm short of the TCP) on the bench top,
    # which is the robot base plane (base at z = 0.80 m on the 0.80 m bench)
    z_stop = recv.getActualTCPPose()[2]
    assert z_stop == pytest.approx(-0.002, abs=0.002)
    _recover(ctrl, recv, standin.host)
    assert ctrl.moveL(pose.tolist(), 0.25, 1.2)  # back up, clear of the bench
    # moveL returns on the control stream; the receive stream may be a few periods behind
    assert _wait(lambda: np.abs(np.array(recv.getActualTCPPose())[:3] - pose[:3]).max() < 1e-6)


def test_watchdog_stops_a_quiet_client(standin, ready):
    ctrl, recv = ready
    assert ctrl.setWatchdog(5.0)  # at least every 0.2 s
    for _ in range(20):  # kicking at ~50 Hz keeps the program alive
        ctrl.kickWatchdog()
        time.sleep(0.02)
    assert recv.getRuntimeState() == 2
    time.sleep(1.0)  # silent for 5 watchdog periods
    assert _wait(lambda: recv.getRuntimeState() == 1)
    assert "RTDE watchdog" in standin.state()["last_error"]
    _recover(ctrl, recv, standin.host)


def _kick_for(ctrl, seconds: float) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        ctrl.kickWatchdog()
        time.sleep(0.02)


def test_watchdog_does_not_blame_the_client_for_a_stand_in_that_fell_behind(standin, ready):
    """The stand-in's own network thread blocked for 0.7 s (a stand-in starved of CPU) while the
    client kicks every 20 ms: the kicks wait unread in the socket, and a 4 Hz watchdog keeps the
    program running. The same stall with a client that stopped kicking stops the program."""
    ctrl, recv = ready
    assert ctrl.setWatchdog(4.0)  # at least every 0.25 s
    _kick_for(ctrl, 0.2)
    assert standin.admin("io_stall 0.7")["ok"]
    _kick_for(ctrl, 1.2)
    assert recv.getRuntimeState() == 2, standin.state()["last_error"]
    assert any("stalls for 0.7 s" in line for line in standin.state()["log_tail"])
    _kick_for(ctrl, 0.2)
    assert standin.admin("io_stall 0.7")["ok"]
    time.sleep(1.0)  # quiet through the stall: nothing waits unread, the watchdog stops it on time
    assert _wait(lambda: recv.getRuntimeState() == 1)
    assert "RTDE watchdog: input_int_register_0 not updated for 0.2" in standin.state()["last_error"]
    _recover(ctrl, recv, standin.host)


def test_io_stall_is_bounded(standin):
    assert standin.admin("io_stall 6")["error"] == "io_stall: at most 5 s"
    assert standin.admin("io_stall 0")["ok"] is False


@pytest.mark.parametrize("args, message", [
    (["--host", "10.0.0.5"], "--host: the stand-in listens on loopback addresses only"),
    (["--host", "localhost-ish"], "--host: not an IP address"),
    (["--version", "4.1"], "--version: expected a controller version"),
    (["--fault", "meteor_strike"], "--fault: unknown fault 'meteor_strike'"),
    (["--q0", "1,2,3"], "--q0: expected 6 comma-separated joint angles"),
    (["--cell", "no/such/cell.toml"], "no/such/cell.toml"),
])
def test_ursim_cli_refuses_bad_options(args, message, capsys):
    assert fabkit_main(["ursim", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_fabkit_urscript_program_runs_on_the_script_port(standin, ready):
    """robot.urscript's program for the demo toolpath, sent to port 30002, runs to the end: the arm
    ends on the last waypoint, the progress register counts to the end, the gripper opened again."""
    import socket

    from _ursim import demo_toolpath
    from robot.urscript import PROGRESS_REGISTER, write_urscript

    ctrl, recv = ready
    ctrl.stopScript()  # the controller runs one program at a time
    tp = demo_toolpath()
    text = write_urscript(tp)
    with socket.create_connection((standin.host, 30002), timeout=5) as s:
        s.sendall(text.encode())
    # the progress register reaches the end a few statements before the program does (gripper, textmsg)
    assert _wait(lambda: standin.state()["out_int"][PROGRESS_REGISTER] == len(tp), timeout=60)
    assert _wait(lambda: standin.state()["runtime_state"] == 1, timeout=5)  # 1: stopped, the program ended
    state = standin.state()
    assert np.abs(np.array(state["q"]) - tp.waypoints[-1]["q"]).max() < 1e-9
    assert not state["digital_out"] & (1 << 16)
    assert any("program fabkit_" in line and "finished" in line for line in state["log_tail"])
