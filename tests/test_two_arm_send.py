"""Lockstep send of a two-arm program: two controller stand-ins on two loopback addresses, one
ur_rtde worker per arm, every sync waypoint reached by both arms before either goes on, a fault of
one arm stopping both, and the resume after it (refused one or three waypoints off before anything
on either controller changes; from the waypoint the send names, both arms meet at the next sync
waypoint and finish the program)."""
from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from tests._ursim import ROOT, StandIn, external_host, free_loopback_hosts

DUAL = ROOT / "cells" / "dual_ur10e.toml"

pytestmark = pytest.mark.skipif(external_host() is not None, reason="two stand-ins with fault injection")


@pytest.fixture(scope="module")
def cell_hosts(tmp_path_factory):
    """The dual cell with a controller `host` for each arm: two loopback addresses free now."""
    import random

    hosts = dict(zip(("a", "b"), free_loopback_hosts(random.Random())))
    text = DUAL.read_text()
    text = text.replace('[robot]                                   # arm "a"\n',
                        f'[robot]                                   # arm "a"\nhost = "{hosts["a"]}"\n')
    text = text.replace('name = "b"\n', f'name = "b"\nhost = "{hosts["b"]}"\n')
    path = tmp_path_factory.mktemp("dualcell") / "dual_ur10e_hosts.toml"
    path.write_text(text)
    return path, hosts


@pytest.fixture(scope="module")
def job(tmp_path_factory, cell_hosts):
    """The middle-clamped tri-fold (3 fold states) planned and checked in the dual cell (with hosts)."""
    import fabkit.pipeline as fk
    from robot.cell import load_cell

    assert {n: m.host for n, m in load_cell(cell_hosts[0]).arms} == cell_hosts[1]
    folder = tmp_path_factory.mktemp("dualjob")
    flat = fk.unfold(fk.relax(fk.generate("trifold")))
    folds = fk.refold(flat, frames=3, fixed_face=4)
    program = fk.plan(folds, cell_hosts[0], workdir=folder)
    assert program.ok, program.problems
    checked = fk.check(program)
    assert checked.ok, checked.problems
    return program, checked


@pytest.fixture()
def standins(tmp_path, cell_hosts):
    arms = {}
    try:
        for arm in ("a", "b"):
            arms[arm] = StandIn("--cell", str(DUAL), "--arm", arm, "--unlock-delay", "0.2", "-v",
                                log=tmp_path / f"ursim_{arm}.log", host=cell_hosts[1][arm])
        yield arms
    finally:
        for s in arms.values():
            s.stop()


def _send(program, checked, standins, tmp_path, *extra, cell_hosts: bool = False, **popen):
    """`fabkit send` of the job to the stand-ins: with --host for each arm, or (`cell_hosts`) none,
    the cell naming them."""
    log = tmp_path / "send.log"
    hosts = [] if cell_hosts else ["--host", standins["a"].host, "--host", standins["b"].host]
    cmd = [sys.executable, "-m", "fabkit", "send", str(program.path_file), "--check", str(checked.check_file),
           "--cell", str(program.cell.source), *hosts, "--log", str(log), "--report", str(tmp_path / "send.json"),
           *extra]
    return subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **popen), log


def _events(log: Path) -> list[dict]:
    """The send log's events so far: its complete lines (the sender may be writing the last one)."""
    lines = log.read_text().split("\n")[:-1]
    return [json.loads(line) for line in lines if line.strip()]


def _synced(events, atp, sync) -> None:
    """Both arms arrive at every sync waypoint of `sync` before either passes it."""
    for k in sync:
        arrived = [e["t"] for e in events if e.get("step") == "sync arrived" and e["waypoint"] == k]
        passed = [e["t"] for e in events if e.get("step") == "sync passed" and e["waypoint"] == k]
        assert len(arrived) == len(passed) == 2, k
        assert max(arrived) <= min(passed) + 1e-3


def test_a_fault_on_one_arm_stops_both_and_the_resume_finishes(job, standins, tmp_path):
    """Both arms fold in lockstep; a protective stop on arm b's controller once both arms passed
    the first fold state stops arm a too, and the report names each arm's last completed waypoint
    and the resume; the resume finishes the program (`_resume_after_the_fault`)."""
    program, checked = job
    atp = program.toolpath
    trigger = atp.sync[1]          # the first fold state
    proc, log = _send(program, checked, standins, tmp_path)
    fired = {}

    def inject():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if log.exists() and sum(1 for e in _events(log) if e.get("step") == "sync passed"
                                    and e["waypoint"] == trigger) == 2 \
                    and all(s.state()["arm_mode"] == "traj" for s in standins.values()):  # both folding
                fired["t"] = time.time()
                standins["b"].admin("protective_stop")
                return
            time.sleep(0.02)

    th = threading.Thread(target=inject)
    th.start()
    out, err = proc.communicate(timeout=240)
    th.join(10)
    assert "t" in fired, err
    assert proc.returncode == 1, err
    # the fault names arm b (the stop itself, or its controller refusing the next path under it)
    assert "stopped: arm b:" in err and "arm a" in err, err
    report = json.loads((tmp_path / "send.json").read_text())
    last = report["last_completed_per_arm"]
    nxt = atp.sync[2]
    assert all(trigger <= k < nxt for k in last.values()), last
    # arm a is at rest: its joints do not change any more
    qa = np.array(standins["a"].state()["q"])
    time.sleep(0.2)
    np.testing.assert_allclose(standins["a"].state()["q"], qa, atol=1e-9)
    ev = _events(log)
    _synced(ev, atp, [k for k in atp.sync if k <= trigger])
    assert {e["arm"] for e in ev if e.get("call") == "move_path"} == {"a", "b"}
    stop_a = [e["t"] for e in ev if e.get("step") == "stop" and e["arm"] == "a"]
    assert stop_a and stop_a[0] - fired["t"] < 1.0
    print(f"arm a stopped {stop_a[0] - fired['t']:.3f} s after the fault on arm b")
    assert any(e.get("step") == "done" and e["arm"] == "a" and "arm b stopped" in (e.get("reason") or "") for e in ev)
    _resume_after_the_fault(program, checked, standins, tmp_path, err, report)


LOADED = "RTDE Control Script Loaded"


def _resume_after_the_fault(program, checked, standins, tmp_path, err, report):
    """The resume the stopped send named: one and three waypoints past the last one both arms
    accept are refused (exit 2, one line naming the arm) with arm b still in its protective stop
    and no control script uploaded to either controller; the named one finishes the program."""
    from robot.interlock import StartTolerances
    from robot.lockstep import resume_start
    from robot.path_chunks import SendError

    atp = program.toolpath
    told = int(re.search(r"continue with --resume-from (\d+)", err).group(1))
    assert report["resume"]["resume_from"] == told and report["resume"]["meet_at"] in (*atp.sync, len(atp) - 1)
    states = {arm: s.state() for arm, s in standins.items()}
    accepted = []  # every arm on its path into k or at the meeting point, at least one on its path
    for k in range(1, len(atp)):
        try:
            starts = [resume_start(atp.arm(arm).waypoints, atp.sync, k, st["q"], st["tcp_pose"], StartTolerances(),
                                   arm) for arm, st in states.items()]
            if k in starts:
                accepted.append(k)
        except SendError:
            pass
    assert told in accepted and accepted == list(range(accepted[0], accepted[-1] + 1)) and len(accepted) <= 2, \
        (told, accepted)
    uploads = {arm: s.log_text().count(LOADED) for arm, s in standins.items()}
    t0 = time.monotonic()
    for k in (accepted[-1] + 1, accepted[-1] + 3):
        proc, _ = _send(program, checked, standins, tmp_path, "--resume-from", str(k), "--unlock", cell_hosts=True)
        _, refused = proc.communicate(timeout=120)
        assert proc.returncode == 2 and f"--resume-from {k}:" in refused and "arm " in refused \
            and refused.count("\n") == 1, refused
        assert standins["b"].state()["safety_mode"] == "PROTECTIVE_STOP", "the refused resume unlocked arm b"
        for arm, s in standins.items():
            assert s.log_text().count(LOADED) == uploads[arm], f"the refused resume uploaded to arm {arm}"
            assert s.state()["q"] == states[arm]["q"]
    t1 = time.monotonic()
    proc, log = _send(program, checked, standins, tmp_path, "--resume-from", str(told), "--unlock",
                      cell_hosts=True)  # the controllers the cell names
    _, err = proc.communicate(timeout=240)
    assert proc.returncode == 0, err
    print(f"resume from {told} (accepted {accepted}, meet at {report['resume']['meet_at']}): two refusals "
          f"{t1 - t0:.1f} s, the resumed send {time.monotonic() - t1:.1f} s")
    for arm, s in standins.items():
        np.testing.assert_allclose(s.state()["q"], atp.arm(arm).waypoints[-1].q, atol=1e-4)
    meet = report["resume"]["meet_at"]
    ev = _events(log)
    _synced(ev, atp, [k for k in atp.sync if k >= meet])
    done = json.loads((tmp_path / "send.json").read_text())
    assert done["hosts"] == {arm: s.host for arm, s in standins.items()}
    assert done["ok"] and done["last_completed_per_arm"] == {"a": len(atp) - 1, "b": len(atp) - 1}
    for arm in standins:  # the resume starts mid-fold: each gripper closed again before the first move
        grips = [e for e in ev if e.get("step") == "gripper" and e["arm"] == arm]
        first_move = min(e["t"] for e in ev if e.get("call") == "move_path" and e["arm"] == arm)
        assert grips[0]["on"] is True and grips[0]["t"] <= first_move and grips[-1]["on"] is False, grips


def _under_way(lock):
    """Both arms of `lock` past their start barrier (waypoint 0), each polling as it waits."""
    other = threading.Thread(target=lock.wait, args=("b", 0, lambda: lock.beat("b")))
    other.start()
    lock.wait("a", 0, lambda: lock.beat("a"))
    other.join(5)
    lock.beat("b")


def test_an_arm_whose_controller_falls_silent_stops_the_others():
    """A ur_rtde call that does not return leaves its arm unable to see its own fault: the other arm's
    next poll after `silence_s` aborts the lockstep, naming the silent arm."""
    from robot.lockstep import Lockstep
    from robot.preflight import ControllerFault

    lock = Lockstep(("a", "b"), (2,), poll_s=0.005, silence_s=0.2)
    lock.beat("a")
    time.sleep(0.25)
    lock.beat("a")  # arm b not under way yet (still preparing): not watched
    _under_way(lock)
    t0 = time.monotonic()
    with pytest.raises(ControllerFault, match="stopped because arm b stopped: its controller did not answer"):
        while time.monotonic() - t0 < 2.0:  # arm a folds on, polling; arm b's call hangs
            lock.beat("a")
            time.sleep(0.01)
    assert 0.2 <= time.monotonic() - t0 < 0.5
    finished = Lockstep(("a", "b"), (2,), poll_s=0.005, silence_s=0.05)
    _under_way(finished)
    finished.finished("b")  # an arm done with its program is not watched
    time.sleep(0.1)
    finished.beat("a")


def test_one_urscript_per_arm_meets_at_every_sync_waypoint(job, tmp_path):
    """`robot.arms_urscript`: each arm's program compiles on the stand-in, with one handshake per
    sync waypoint. On two stand-ins whose handshake lines are wired together (`--wire-output`), arm
    b's program started 2 s after arm a's: both finish at their last waypoints, and no arm ever
    moves past a sync waypoint the other has not reached (arm a waits at the first one)."""
    import random
    import socket

    from robot.arms_urscript import HANDSHAKE_INPUT, HANDSHAKE_OUTPUT, write_arm_urscripts
    from robot.urscript import PROGRESS_REGISTER
    from sim.ursim.urscript import parse_program

    program, _ = job
    atp = program.toolpath
    scripts = write_arm_urscripts(atp)
    for arm, text in scripts.items():
        name, statements = parse_program(text)
        waits = [s for s in statements if s.name == "wait_standard_digital_in"]
        assert name == f"fabkit_fold_dual_ur10e_{arm}" and len(waits) == len(atp.sync) + 1  # the start and every sync
        assert [s.args for s in waits[1:]] == [(HANDSHAKE_INPUT, j % 2 == 1) for j in range(1, len(atp.sync) + 1)]
    hosts = dict(zip(("a", "b"), free_loopback_hosts(random.Random())))
    peer = {"a": "b", "b": "a"}
    arms = {}
    try:
        for arm in ("a", "b"):
            arms[arm] = StandIn("--cell", str(DUAL), "--arm", arm, "-v", "--wire-output",
                                f"{HANDSHAKE_OUTPUT}:{hosts[peer[arm]]}:{HANDSHAKE_INPUT}",
                                log=tmp_path / f"ursim_{arm}.log", host=hosts[arm])
        for arm, delay in (("a", 0.0), ("b", 2.0)):
            time.sleep(delay)
            with socket.create_connection((hosts[arm], 30002), timeout=5.0) as s:
                s.sendall(scripts[arm].encode("ascii"))
        n, seen, deadline = len(atp), [], time.monotonic() + 120.0
        while time.monotonic() < deadline:
            st = {arm: s.state() for arm, s in arms.items()}
            for arm in st:
                assert not st[arm]["last_error"], (arm, st[arm]["last_error"])
            at = {arm: st[arm]["out_int"][PROGRESS_REGISTER] for arm in st}
            seen.append({**at, "a_idle": st["a"]["arm_mode"] == "idle"})
            if all(k == n for k in at.values()):
                break
            time.sleep(0.02)
        else:
            pytest.fail(f"the programs did not finish: {seen[-3:]}; " + arms["a"].log_text()[-1000:])
        for arm, s in arms.items():
            np.testing.assert_allclose(s.state()["q"], atp.arm(arm).waypoints[-1].q, atol=1e-6)
            assert not s.state()["digital_out"] & (1 << HANDSHAKE_OUTPUT)
        for at in seen:  # moving toward a waypoint past sync k only once the other arm has reached k
            for arm, other in peer.items():
                passed = [k for k in atp.sync if at[arm] > k]
                assert not passed or at[other] >= passed[-1], (at, atp.sync)
        waited = [at for at in seen if at["a"] == atp.sync[0] and at["a_idle"] and at["b"] < atp.sync[0]]
        assert len(waited) >= 10, ("arm a did not wait at the first sync waypoint for arm b",
                                   [at for at in seen if at["a"] <= atp.sync[0] + 1][::5])
        print(f"two URScript programs, b started 2 s late: arm a waited {len(waited)} polls at sync {atp.sync[0]}")
    finally:
        for s in arms.values():
            s.stop()


def test_a_urscript_arm_whose_partner_stopped_halts_after_the_timeout(job, tmp_path):
    """The handshake's time-out on two wired stand-ins, 1 s: arm b's program is stopped (the Stop
    button) on its way to the grip. Arm a waits 1 s at the grip (sync waypoint 2), puts its output
    back and halts, naming the sync waypoint and arm b. Arm b's program is then started again: it
    arrives at the grip, does not pass it alone, waits its own 1 s and halts naming the same sync
    waypoint and arm a. Both stand at the grip."""
    import random
    import socket

    from robot.arms_urscript import HANDSHAKE_INPUT, HANDSHAKE_OUTPUT, write_arm_urscripts
    from robot.urscript import PROGRESS_REGISTER

    atp = job[0].toolpath
    k = atp.sync[0]
    scripts = write_arm_urscripts(atp, timeout_s=1.0, start_window_s=0.0)
    hosts = dict(zip(("a", "b"), free_loopback_hosts(random.Random())))
    peer = {"a": "b", "b": "a"}
    arms, seen, events = {}, [], {}

    def start(arm):
        with socket.create_connection((hosts[arm], 30002), timeout=5.0) as s:
            s.sendall(scripts[arm].encode("ascii"))
    try:
        for arm in ("a", "b"):
            arms[arm] = StandIn("--cell", str(DUAL), "--arm", arm, "-v", "--wire-output",
                                f"{HANDSHAKE_OUTPUT}:{hosts[peer[arm]]}:{HANDSHAKE_INPUT}",
                                log=tmp_path / f"ursim_{arm}.log", host=hosts[arm])
        start("a")
        start("b")
        deadline = time.monotonic() + 40.0
        while time.monotonic() < deadline:
            st = {arm: s.state() for arm, s in arms.items()}
            now = time.monotonic()
            seen.append({arm: (now, st[arm]["out_int"][PROGRESS_REGISTER], st[arm]["runtime_state"],
                               bool(st[arm]["digital_out"] & (1 << HANDSHAKE_OUTPUT))) for arm in st})
            at = seen[-1]
            if "stop_b" not in events and at["b"][1] >= 1:  # b on its way to the approach
                arms["b"].admin("program_stop")
                events["stop_b"] = now
            if "a_up" not in events and at["a"][3]:
                events["a_up"] = now
            if "a_up" in events and "a_halted" not in events and at["a"][2] == 1:
                events["a_halted"] = now
                start("b")  # the operator starts arm b's program again
                events["restart_b"] = time.monotonic()
            if "restart_b" in events and now > events["restart_b"] + 0.5 and all(v[2] == 1 for v in at.values()):
                break
            time.sleep(0.02)
        else:
            pytest.fail(f"the programs did not stop: {seen[-1]}, {events}")
        assert max(at["b"][1] for at in seen) == k and max(at["a"][1] for at in seen) == k  # nobody passed
        waited = {}
        for arm, s in arms.items():
            log = s.log_text()
            msg = (f"arm {arm} halted at sync waypoint {k} (1 of {len(atp.sync)}): arm {peer[arm]} did not arrive "
                   "within 1.0 s")
            assert f"popup: {msg}" in log and f"textmsg: fabkit: {msg}" in log and "halted (line" in log, log[-1500:]
            np.testing.assert_allclose(s.state()["q"], atp.arm(arm).waypoints[k].q, atol=1e-6)
            out = [c for c in s.admin("record")["commands"] if c["command"] == "set_standard_digital_out"
                   and c["output"] == HANDSHAKE_OUTPUT]
            # a: reset, at sync 1, put back; b: reset (stopped), reset again, at sync 1, put back
            assert [c["value"] for c in out] == ([False, True, False] if arm == "a" else [False, False, True, False])
            waited[arm] = out[-1]["t"] - out[-2]["t"]  # controller time from arriving to the time-out
            # never shorter; longer by the ticks the stand-in's program thread missed on a loaded machine
            assert 1.0 <= waited[arm] <= 1.0 + 0.25, (arm, waited[arm])
        up = {arm: [at[arm][0] for at in seen if at[arm][3]] for arm in arms}
        assert up["b"][0] > up["a"][-1]  # b arrived after a had timed out and put its output back
        print(f"arm b stopped; arm a waited {waited['a']:.3f} s of controller time at sync waypoint {k} "
              f"({up['a'][-1] - up['a'][0]:.2f} s between the polls that saw its output up) and halted; "
              f"arm b, started again, waited {waited['b']:.3f} s there and halted")
    finally:
        for s in arms.values():
            s.stop()


def test_the_default_handshake_timeout_is_the_longest_segment_plus_the_margin(job):
    """The default time-out (`robot.arms_urscript.default_timeout`) is the longest segment between
    sync waypoints of either arm in the motion model plus 2 s, rounded up to 0.1 s, so an arm that
    runs the program at full speed never trips it; every sync wait carries it, the start line and
    the first sync waypoint 10 s more."""
    from robot.arms_urscript import START_WINDOW_S, TIMEOUT_MARGIN_S, default_timeout, write_arm_urscripts
    from robot.motion import toolpath_cycle_time
    from sim.ursim.urscript import parse_program

    atp = job[0].toolpath
    bounds = [0, *atp.sync, len(atp) - 1]
    longest = 0.0
    for name, tp in atp.arms:  # the segments from the cycle time's own per-move times and the dwells
        seg = toolpath_cycle_time(tp).segments
        grip = tp.extra["grip"]
        for a, b in zip(bounds[:-1], bounds[1:]):
            dwell = {"grip": grip["grip_dwell_s"], "release": grip["release_dwell_s"]}.get(tp.waypoints[b].op, 0.0)
            longest = max(longest, float(seg[a:b].sum()) + dwell)
    timeout = default_timeout(atp)
    assert longest + TIMEOUT_MARGIN_S <= timeout < longest + TIMEOUT_MARGIN_S + 0.1 and 5.0 < longest < 60.0
    for arm, text in write_arm_urscripts(atp).items():
        waits = [s.kwargs["timeout"] for s in parse_program(text)[1] if s.name == "wait_standard_digital_in"]
        assert waits == pytest.approx([timeout + START_WINDOW_S] * 2 + [timeout] * (len(atp.sync) - 1), abs=1e-12)
