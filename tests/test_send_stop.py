"""The arm stops whatever dies, and a resume starts only where the arm is (on the controller stand-in).

`kill -9` and `kill -STOP` of the ur_rtde worker and `kill -9` of `fabkit send` mid-path: the
stand-in's arm is stopped within 0.5 s (its RTDE watchdog, armed by the sender) and the send log
so far is on disk; SIGTERM stops the arm and closes the log. `--resume-from` one or three
waypoints past the right one is refused before anything on the controller changes (the protective
stop stays, no control script is uploaded)."""
import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from _ursim import demo_job_fixture, CELL, ROOT, StandIn, external_host, move_to

pytestmark = [pytest.mark.network, pytest.mark.skipif(external_host() is not None,
                                                      reason="fault injection needs the stand-in")]
LOADED = "RTDE Control Script Loaded"


@pytest.fixture(scope="module")
def standin(tmp_path_factory):
    s = StandIn("--cell", str(CELL), "--unlock-delay", "0.2", "-v", log=tmp_path_factory.mktemp("ursim") / "ursim.log")
    try:
        yield s
    finally:
        s.stop()


job = demo_job_fixture()


@pytest.fixture(autouse=True)
def healthy(standin, job):
    standin.admin("normal")
    standin.admin("program_stop")
    q0 = job[0].waypoints[0].q
    if np.abs(np.subtract(standin.state()["q"], q0)).max() > 1e-6:
        move_to(standin.host, q0)
    yield
    standin.admin("normal")


def start_send(job, host, log, *extra):
    tp, path, check = job
    return subprocess.Popen([sys.executable, "-m", "fabkit", "send", str(path), "--check", str(check), "--cell",
                             str(CELL), "--host", host, "--log", str(log), *extra], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def wait_mid_path(standin, proc, progress=10):
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        st = standin.state()
        if st["arm_mode"] == "traj" and st["out_int"][2] & 0x7FFF >= progress:
            return
        time.sleep(0.01)
    out, err = proc.communicate(timeout=10)
    pytest.fail(f"the send never got mid-path: rc {proc.returncode}, {err[-1500:]}, {standin.state()['log_tail']}")


def worker_pid(log) -> int:
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        for line in log.read_text().split("\n")[:-1]:  # complete lines: the sender may be writing the last
            e = json.loads(line)
            if e.get("worker") == "started":
                return int(e["pid"])
        time.sleep(0.05)
    raise AssertionError("no worker in the log")


def seconds_to_stop(standin, t0, limit=3.0) -> float:
    """Time from t0 until the stand-in's arm is idle and stays put for 0.2 s."""
    while time.monotonic() - t0 < limit:
        st = standin.state()
        if st["arm_mode"] == "idle":
            dt = time.monotonic() - t0
            q = st["q"]
            time.sleep(0.2)
            assert standin.state()["q"] == q, "the arm moved after it stopped"
            return dt
        time.sleep(0.005)
    pytest.fail(f"the arm did not stop within {limit} s: {standin.state()['log_tail'][-5:]}")


def logged(log) -> list[dict]:
    lines = log.read_text().splitlines()
    return [json.loads(line) for line in lines]


def gone(pid: int, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        try:  # a zombie of a parent we killed
            if open(f"/proc/{pid}/stat").read().split()[2] == "Z":
                return True
        except OSError:
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("how", ["kill -9 worker", "kill -STOP worker", "kill -9 send"])
def test_the_arm_stops_whatever_dies(standin, job, tmp_path, how):
    log = tmp_path / "send.log"
    proc = start_send(job, standin.host, log)
    wpid = None
    try:
        wait_mid_path(standin, proc)
        wpid = worker_pid(log)
        victim, sig = (proc.pid, signal.SIGKILL) if how.endswith("send") else \
            (wpid, signal.SIGSTOP if "STOP" in how else signal.SIGKILL)
        t0 = time.monotonic()
        os.kill(victim, sig)
        dt = seconds_to_stop(standin, t0)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    print(f"{how}: the arm stopped {dt:.3f} s after the kill")
    assert dt <= 0.5, f"{how}: the arm stopped {dt:.3f} s after the kill"
    # the watchdog, or (the sender died) its orphaned worker stopping the arm before it exits
    tail = "\n".join(standin.state()["log_tail"])
    assert "RTDE watchdog" in tail or "stop script" in tail or how == "kill -9 worker", tail
    events = logged(log)  # complete JSON lines as far as the send got
    assert any(e.get("call") == "move_path" for e in events)
    if how.endswith("send"):
        assert proc.returncode == -signal.SIGKILL
        assert gone(wpid), "the worker outlived its parent"
    else:
        assert proc.returncode == 1, err
        m = re.search(r"stopped: controller link lost: ur_rtde (worker died|call state did not return)", err)
        assert m, err
        assert events[-1]["step"] == "done" and not events[-1]["ok"]
        stops = [e["how"] for e in events if e.get("step") == "stop"]
        assert stops and "dashboard stop: Stopped" in stops[-1]
        assert gone(wpid)


def test_sigterm_stops_the_arm_and_writes_the_log(standin, job, tmp_path):
    log = tmp_path / "send.log"
    proc = start_send(job, standin.host, log)
    try:
        wait_mid_path(standin, proc)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        dt = seconds_to_stop(standin, t0)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130 and "interrupted" in err
    assert dt <= 0.5
    events = logged(log)
    # stopL blocks until the arm rests: the watchdog may end the program first (both stop the arm)
    assert [e for e in events if e.get("step") == "stop"][-1]["how"] in (
        "stopL done", "stopL returned False (control script not running: the arm is stopped)")
    assert events[-1]["step"] == "done" and events[-1]["reason"] == "interrupted"


def test_resume_one_or_three_waypoints_off_is_refused_before_anything_changes(standin, job, tmp_path):
    tp, path, check = job
    assert standin.admin("at_progress 20 protective_stop injected by the test")["ok"]
    p = subprocess.run([sys.executable, "-m", "fabkit", "send", str(path), "--check", str(check), "--cell", str(CELL),
                        "--host", standin.host], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 1, p.stderr
    last = int(re.search(r"last completed waypoint (\d+)", p.stderr).group(1))
    assert standin.state()["safety_mode"] == "PROTECTIVE_STOP"
    uploads = standin.log_text().count(LOADED)
    q_stop = standin.state()["q"]
    # where the arm stands decides the right N: the resume rule accepts only the move the arm is on
    # (two where the last blend radius before a waypoint begins the next move), never one past the
    # waypoint the sender reported
    from robot.interlock import verify_start
    from robot.sender import SendError

    st = standin.state()
    ok = []
    for n in range(1, len(tp)):
        try:
            verify_start(tp.waypoints, n, st["q"], st["tcp_pose"])
            ok.append(n)
        except SendError:
            pass
    assert ok and len(ok) <= 2 and ok == list(range(ok[0], ok[0] + len(ok))) and last + 1 <= ok[-1], (last, ok)
    right = ok[-1]
    for n in (ok[-1] + 1, ok[-1] + 3):  # one and three waypoints past the last acceptable one
        r = subprocess.run([sys.executable, "-m", "fabkit", "send", str(path), "--check", str(check), "--cell",
                            str(CELL), "--host", standin.host, "--resume-from", str(n), "--unlock"], cwd=ROOT,
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and f"--resume-from {n}: the TCP is" in r.stderr and r.stderr.count("\n") == 1, \
            r.stderr
        st = standin.state()
        assert st["safety_mode"] == "PROTECTIVE_STOP", "the refused resume unlocked the protective stop"
        assert standin.log_text().count(LOADED) == uploads, "the refused resume uploaded a control script"
        assert st["q"] == q_stop
    r = subprocess.run([sys.executable, "-m", "fabkit", "send", str(path), "--check", str(check), "--cell", str(CELL),
                        "--host", standin.host, "--resume-from", str(right), "--unlock"], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert np.abs(np.array(standin.state()["q"]) - tp.waypoints[-1].q).max() < 1e-9


def test_resume_with_the_tool_turned_is_refused(standin, job):
    """Position right, orientation wrong: the arm at waypoint 20's position with the tool turned."""
    from robot.cell import load_cell, pose_to_matrix
    from robot import kinematics as K
    from robot.interlock import StartTolerances, verify_start
    from robot.sender import SendError

    tp = job[0]
    cell = load_cell(CELL)
    w = tp.waypoints[20]
    T = pose_to_matrix(w.pose)
    c, s = np.cos(0.02), np.sin(0.02)
    T[:3, :3] = T[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    q = K.select_nearest(K.ik(cell.model, T, cell.tool.tcp), np.array(w.q), model=cell.model)
    from robot.cell import matrix_to_pose

    verify_start(tp.waypoints, 21, w.q, w.pose, StartTolerances())  # exactly at waypoint 20: fine
    with pytest.raises(SendError, match="--resume-from 21: the tool is turned 1.15°"):
        verify_start(tp.waypoints, 21, q, matrix_to_pose(T), StartTolerances())
