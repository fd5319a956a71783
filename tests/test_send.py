"""`fabkit send` end to end on the controller stand-in (or FABKIT_UR_HOST): a demo toolpath with a
real MuJoCo check runs to completion and ends on its last waypoint; a protective stop mid-path
exits 1 within 2 s naming the last completed waypoint and `--resume-from` finishes the job; bad
checks are refused before anything is sent."""
import json
import re
import subprocess
import sys
import time

import numpy as np
import pytest

from _ursim import demo_job_fixture, CELL, ROOT, external_host, move_to, standin_fixture
from fabkit.cli import main as fabkit_main

pytestmark = pytest.mark.network
needs_standin = pytest.mark.skipif(external_host() is not None, reason="fault injection needs the stand-in")


standin = standin_fixture("--cell", str(CELL), unlock_delay="1", external_ok=True)


def run_fabkit(capsys, *args):
    """`fabkit ARGS` in this process (ur_rtde still runs in the sender's worker process)."""
    capsys.readouterr()
    rc = fabkit_main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(args, rc, out, err)


@pytest.fixture(scope="module")
def host(standin):
    return external_host() or standin.host


job = demo_job_fixture()


def test_send_runs_the_demo_toolpath_to_completion(standin, host, job, tmp_path, capsys):
    tp, path, check = job
    if standin is None:  # a real URSim / robot: start where the toolpath starts
        move_to(host, tp.waypoints[0]["q"])
    log, report = tmp_path / "send.log", tmp_path / "report.json"
    r = run_fabkit(capsys, "send", str(path), "--check", str(check), "--cell", str(CELL), "--host", host, "--log", str(log), "--report", str(report))
    assert r.returncode == 0, r.stderr
    assert f"sent {len(tp)} of {len(tp)} waypoints" in r.stdout
    rep = json.loads(report.read_text())
    # chunks end at grip (waypoint 2) and release (57): 0-2, 2-52, 52-57, 57-59
    assert rep["ok"] and rep["last_completed"] == len(tp) - 1 and rep["chunks_sent"] == 4
    assert rep["final_error_m"] < 1e-6 and rep["final_error_rad"] < 1e-6
    assert rep["quantisation_m"] < 1e-6 and rep["quantisation_rad"] < 1e-5
    events = [json.loads(line) for line in log.read_text().splitlines()]
    calls = [e["call"] for e in events if "call" in e]
    # read-only first (model, remote control, where the arm is), then changes, the upload, the watchdog
    assert calls[:5] == ["connect_dashboard", "dashboard", "dashboard", "connect_receive", "state"]
    assert calls.index("connect_control") < calls.index("set_tcp") < calls.index("arm_watchdog") < calls.index("move_path")
    assert calls.count("move_path") == 4 and "set_tcp" in calls and calls[-2:] == ["stop_script", "disconnect"]
    assert events[0]["step"] == "cleared" and events[0]["toolpath_sha256"] == tp.sha256
    assert rep["toolpath_sha256"] == tp.sha256 and 0 < rep["recheck_s"]
    grips = [e["on"] for e in events if e.get("step") == "gripper"]
    assert grips == [False, True, False]  # released at the start, closed at grip, opened at release
    if standin is not None:
        state = standin.state()
        assert np.abs(np.array(state["q"]) - tp.waypoints[-1]["q"]).max() < 1e-9
        assert state["tcp_offset"] == pytest.approx(list(tp.tcp), abs=1e-12)
        assert not state["digital_out"] & (1 << 16)  # tool output 0 off again


@needs_standin
def test_protective_stop_mid_path_then_resume(standin, host, job, tmp_path, capsys):
    tp, path, check = job
    report = tmp_path / "report.json"
    assert standin.admin("at_progress 20 protective_stop injected by the test")["ok"]
    proc = subprocess.Popen([sys.executable, "-m", "fabkit", "send", str(path), "--check", str(check), "--cell", str(CELL), "--host", host,
                             "--report", str(report)], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        t_stop = None
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if standin.state()["safety_mode"] == "PROTECTIVE_STOP":
                t_stop = time.monotonic()
                break
            time.sleep(0.01)
        if t_stop is None:
            out, err = proc.communicate(timeout=30)
            pytest.fail(f"the protective stop never happened: rc {proc.returncode}, {err[-1500:]}, "
                        f"{standin.state()['log_tail']}")
        out, err = proc.communicate(timeout=30)
        t_exit = time.monotonic()
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, err
    assert t_exit - t_stop < 2.0
    m = re.search(r"stopped: protective stop; last completed waypoint (\d+) of 59; continue with --resume-from (\d+)",
                  err)
    assert m, err
    last = int(m.group(1))
    # progress 20 of the chunk that starts at waypoint 2 (grip): the arm was on its way to waypoint 22
    assert 21 <= last <= 22 and int(m.group(2)) == last + 1
    assert json.loads(report.read_text())["last_completed"] == last
    assert standin.state()["digital_out"] & (1 << 16)  # stopped while gripping: the gripper stays closed
    q_stop = np.array(standin.state()["q"])
    time.sleep(0.2)
    assert np.array_equal(np.array(standin.state()["q"]), q_stop)  # the arm stays stopped
    # resume: unlock (the stand-in's unlock delay is 1 s here) and finish the job
    r = run_fabkit(capsys, "send", str(path), "--check", str(check), "--cell", str(CELL), "--host", host, "--resume-from", str(last + 1), "--unlock")
    assert r.returncode == 0, r.stderr
    assert f"sent {len(tp) - last - 1} of {len(tp)} waypoints" in r.stdout
    assert np.abs(np.array(standin.state()["q"]) - tp.waypoints[-1]["q"]).max() < 1e-9
    assert not standin.state()["digital_out"] & (1 << 16)


@needs_standin
def test_resume_far_from_the_path_is_refused(standin, host, job, capsys):
    tp, path, check = job
    r = run_fabkit(capsys, "send", str(path), "--check", str(check), "--cell", str(CELL), "--host", host, "--resume-from", "30")
    assert r.returncode == 2
    assert "--resume-from 30: the TCP is" in r.stderr and r.stderr.count("\n") == 1
    assert standin.state()["program"] is None or standin.state()["runtime_state"] != 2  # nothing was uploaded


def test_failed_check_is_refused(job, tmp_path, capsys):
    tp, path, check = job
    bad = tmp_path / "CHECK.json"
    data = json.loads(check.read_text())
    data.update(ok=False, problems=[{"waypoint": 12, "kind": "collision", "detail": "wrist_3 x bench"}])
    bad.write_text(json.dumps(data))
    r = run_fabkit(capsys, "send", str(path), "--check", str(bad), "--cell", str(CELL), "--host", "127.0.0.254")
    assert r.returncode == 1
    assert "refusing to send" in r.stderr and "waypoint 12: collision" in r.stderr and r.stderr.count("\n") == 1


def test_check_of_another_toolpath_is_refused(job, tmp_path, capsys):
    tp, path, check = job
    other = tmp_path / "CHECK.json"
    data = json.loads(check.read_text())
    data["toolpath_sha256"] = "0" * 64
    other.write_text(json.dumps(data))
    r = run_fabkit(capsys, "send", str(path), "--check", str(other), "--cell", str(CELL), "--host", "127.0.0.254")
    assert r.returncode == 2
    assert "does not match the toolpath" in r.stderr and r.stderr.count("\n") == 1


def test_edited_toolpath_is_refused(job, tmp_path, capsys):
    tp, path, check = job
    edited = tmp_path / "PATH.json"
    d = json.loads(path.read_text())
    d["waypoints"][5]["pose"][2] += 0.01  # moved after checking: the file's hash no longer matches
    edited.write_text(json.dumps(d))
    r = run_fabkit(capsys, "send", str(edited), "--check", str(check), "--cell", str(CELL), "--host", "127.0.0.254")
    assert r.returncode == 2 and "sha256 does not match" in r.stderr and r.stderr.count("\n") == 1


def test_printed_matches_ur_rtde_path_printing(rng):
    """The sender's model of ur_rtde's path number printing is checked against ur_rtde itself."""
    import rtde_control

    from robot.sender import printed

    values = np.r_[rng.uniform(-2, 2, 200), rng.uniform(-1e-3, 1e-3, 20), [1e-7, 1234.56789, 0.123456789, 0.0]]
    for chunk in np.array_split(values, 40):
        pose = list(chunk[:6]) + [0.0] * (6 - len(chunk[:6]))
        path = rtde_control.Path()
        E = rtde_control.PathEntry
        path.addEntry(E(E.MoveL, E.PositionTcpPose, pose + [0.25, 1.2, 0.0]))
        text = re.search(r"movel\(p\[([^\]]*)\]", path.toScriptCode()).group(1)
        assert [float(x) for x in text.split(",")] == [printed(x) for x in pose]


def test_overlapping_blends_are_refused_before_sending(job, tmp_path, capsys):
    from robot.sender import SendError, validate_waypoints

    tp, path, check = job
    wps = [w.to_json() for w in tp.waypoints]
    validate_waypoints(wps)
    seg = np.linalg.norm(np.subtract(wps[11]["pose"][:3], wps[10]["pose"][:3]))
    wps[10]["r"] = wps[11]["r"] = 0.6 * seg
    with pytest.raises(SendError, match=r"waypoints (9-10|10-11): blend radii .* overlap"):
        validate_waypoints(wps)
    wps = [w.to_json() for w in tp.waypoints]
    wps[-1]["r"] = 0.001
    with pytest.raises(SendError, match="last waypoint must have blend radius 0"):
        validate_waypoints(wps)
    wps = [w.to_json() for w in tp.waypoints]
    wps[3]["v"] = 3.5
    with pytest.raises(SendError, match=r"waypoint 3: speed 3.5 m/s outside \(0, 3.0\]"):
        validate_waypoints(wps)


def test_chunk_entries_keep_rounded_blends_apart():
    """Blends at exactly half the segment would overlap once ur_rtde rounds the positions; the
    sender shrinks them to just under half of the rounded segments, and ends every chunk at rest."""
    from robot.sender import chunk_entries, printed

    base = np.array([-0.4123456789, 0.1111111111, 0.3333333333, 2.2, 2.2, 0.0])
    wps = []
    for k in range(6):
        p = base + np.array([0.0123456789 * k, 0.0, 0.0, 0, 0, 0])
        wps.append({"pose": list(p), "q": [0.0] * 6, "move": "movel", "v": 0.25, "a": 1.2,
                    "r": 0.5 * 0.0123456789 if 0 < k < 5 else 0.0, "op": "fold", "state": 0})
    entries, qm, qr, red = chunk_entries(wps, 0, 6)
    assert [e[0] for e in entries] == ["movel"] * 6
    assert entries[0][2][8] == 0.0 and entries[-1][2][8] == 0.0
    pos = np.array([[printed(x) for x in e[2][:3]] for e in entries])
    seg = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    r = np.array([e[2][8] for e in entries])
    assert np.all(r[:-1] + r[1:] < seg)  # no overlap after rounding
    assert 0 < red < 1e-4 and qm <= 5e-7 and qr <= 5e-6


def test_no_controller_at_the_address(job, capsys):
    import random

    from _ursim import free_loopback_hosts

    tp, path, check = job
    nobody = free_loopback_hosts(random.Random(7))[0]
    r = run_fabkit(capsys, "send", str(path), "--check", str(check), "--cell", str(CELL), "--host", nobody)
    assert r.returncode == 1
    assert "stopped: ur_rtde error: RuntimeError: Timeout connecting to UR dashboard server." in r.stderr
    assert "last completed waypoint -1 of 59" in r.stderr
