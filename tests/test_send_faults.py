"""`fabkit send` under link faults injected into the stand-in: the RTDE connection dropped and the
stream stalled mid-path end with exit 1 in bounded time (ur_rtde may segfault in its worker; the
command survives), a second control client gets IN_USE, and a controller too slow to answer trips
the per-call timeout instead of hanging."""
import json
import re
import time

import numpy as np
import pytest

from _ursim import demo_job_fixture, CELL, external_host, free_loopback_hosts, move_to, standin_fixture
from fabkit.cli import main as fabkit_main

pytestmark = [pytest.mark.network, pytest.mark.skipif(external_host() is not None,
                                                      reason="fault injection needs the stand-in")]


standin = standin_fixture("--cell", str(CELL), unlock_delay="0.2")


job = demo_job_fixture()


@pytest.fixture(autouse=True)
def healthy(standin, job):
    """Every test starts with a healthy controller, no program running and the arm at waypoint 0."""
    standin.admin("normal")
    standin.admin("program_stop")
    standin.admin("estop_release")
    q0 = job[0].waypoints[0]["q"]
    if np.abs(np.subtract(standin.state()["q"], q0)).max() > 1e-6:
        move_to(standin.host, q0)
    yield
    standin.admin("normal")
    standin.admin("estop_release")


def send(capsys, *args):
    capsys.readouterr()
    t0 = time.monotonic()
    rc = fabkit_main(["send", *args])
    out, err = capsys.readouterr()
    return rc, out, err, time.monotonic() - t0


@pytest.mark.parametrize("fault, reason", [
    ("drop_rtde", r"(controller link lost|RTDE stream stalled|control script restarted mid-move)"),
    ("stall 30", r"RTDE stream stalled"),
    ("program_stop", r"the control script stopped \(program stopped on the controller\)"),
])
def test_link_faults_mid_path_end_in_bounded_time(standin, job, tmp_path, capsys, fault, reason):
    tp, path, check = job
    assert standin.admin(f"at_progress 15 {fault}")["ok"]
    report = tmp_path / "r.json"
    rc, out, err, dt = send(capsys, str(path), "--check", str(check), "--cell", str(CELL), "--host", standin.host, "--report", str(report))
    assert rc == 1, err
    assert dt < 30
    assert re.search(reason, err), err
    rep = json.loads(report.read_text())
    # the link is gone, so the arm may go on past waypoint 15 (the program keeps running on the
    # controller); what the sender saw last is what it reports
    assert 13 <= rep["last_completed"] < len(tp) - 1
    assert f"last completed waypoint {rep['last_completed']} of {len(tp) - 1}" in err


def test_second_control_client_gets_in_use(standin, job, capsys):
    import rtde_control

    tp, path, check = job
    holder = rtde_control.RTDEControlInterface(standin.host, -1.0, rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT,
                                               50002, -1)
    try:
        rc, out, err, dt = send(capsys, str(path), "--check", str(check), "--cell", str(CELL), "--host", standin.host)
    finally:
        holder.disconnect()
    assert rc == 1
    assert "One of the RTDE input registers are already in use" in err


def test_slow_controller_trips_the_call_timeout(standin, job):
    from robot.sender import SendSettings, send_toolpath

    tp, path, check = job
    assert standin.admin("slow 3")["ok"]  # every dashboard and RTDE setup reply 3 s late
    t0 = time.monotonic()
    from robot.cell import load_cell

    cell = load_cell(CELL)
    check_data = json.loads(check.read_text())
    result = send_toolpath(tp, check_data, cell, SendSettings(host=standin.host, connect_timeout_s=1.0,
                                                              call_timeout_s=1.0))
    assert time.monotonic() - t0 < 10
    assert not result.ok
    assert result.reason.startswith("controller link lost: ur_rtde call connect_dashboard did not return within 1 s")
    assert result.last_completed == -1


def test_emergency_stop_is_refused_by_preflight(standin, job, capsys):
    tp, path, check = job
    assert standin.admin("estop")["ok"]
    rc, out, err, dt = send(capsys, str(path), "--check", str(check), "--cell", str(CELL), "--host", standin.host)
    assert rc == 1 and "preflight: 'Safetystatus: ROBOT_EMERGENCY_STOP'" in err
    standin.admin("estop_release")  # the robot is powered off afterwards: --power-on brings it back
    rc, out, err, dt = send(capsys, str(path), "--check", str(check), "--cell", str(CELL), "--host", standin.host)
    assert rc == 1 and "Robotmode: POWER_OFF" in err and "--power-on" in err
    rc, out, err, dt = send(capsys, str(path), "--check", str(check), "--cell", str(CELL), "--host", standin.host, "--power-on", "--chunk", "30")
    assert rc == 0, err
    assert "(4 path chunk(s))" in out  # waypoints 0-2 (grip), 2-31, 31-57 (release), 57-59


def test_worker_is_killed_when_it_hangs():
    """A worker call that does not return in time: the worker is killed, the caller gets WorkerError."""
    import socket

    from robot.rtde_worker import RTDEWorker, WorkerError

    # a "dashboard" that accepts connections (kernel backlog) but never greets: ur_rtde waits for it
    import random

    host = free_loopback_hosts(random.Random())[0]
    mute = socket.socket()
    mute.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    mute.bind((host, 29999))
    mute.listen(4)
    w = RTDEWorker(host)
    try:
        t0 = time.monotonic()
        with pytest.raises(WorkerError, match="did not return within 0.5 s"):
            w.call("connect_dashboard", timeout=0.5)
        assert time.monotonic() - t0 < 3
        assert w.proc.poll() is not None
        with pytest.raises(WorkerError):
            w.call("state")
    finally:
        w.kill()
        mute.close()


def test_toolpath_for_another_robot_model_is_refused(standin, job, tmp_path, capsys):
    import dataclasses

    tp, path, check = job
    other = dataclasses.replace(tp, robot="ur10e")  # same waypoints, planned for a UR10e: another hash
    other_path = tmp_path / "PATH.json"
    other.save(other_path)
    rc, out, err, dt = send(capsys, str(other_path), "--check", str(check), "--cell", str(CELL), "--host", standin.host)
    assert rc == 2 and err.count("\n") == 1
    assert "this check was made for another toolpath" in err


def test_ctrl_c_stops_the_arm(standin, job):
    """Ctrl-C reaches the sender and its worker (one process group): the worker ignores it so that
    the sender can still stop the arm, then the command exits 130."""
    import os
    import signal
    import subprocess
    import sys

    from _ursim import ROOT

    tp, path, check = job
    proc = subprocess.Popen([sys.executable, "-m", "fabkit", "send", str(path), "--check", str(check), "--cell", str(CELL), "--host",
                             standin.host], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while standin.state()["out_int"][2] & 0x7FFF < 10 and time.monotonic() < deadline:
            time.sleep(0.01)
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130 and "interrupted" in err
    q1 = standin.state()["q"]
    time.sleep(0.3)
    assert standin.state()["q"] == q1 and standin.state()["arm_mode"] == "idle"
