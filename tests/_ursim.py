"""Test helpers for the controller stand-in: run it as a subprocess on a loopback address, build a
demo toolpath in the ur5e_bench cell and its real MuJoCo check report.

`FABKIT_UR_HOST` points the same tests at a real URSim or robot instead (`ur_host()`); the
fault-injection tests skip themselves there.
"""
from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / "tests" / "data" / "ursim_bench.toml"  # fixed, so shared cell edits do not move the tests


def external_host() -> str | None:
    return os.environ.get("FABKIT_UR_HOST") or None


def wait_for_banner(host: str, timeout: float = 20.0, port: int = 29999) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError):
            with socket.create_connection((host, port), timeout=1.0) as s:
                s.settimeout(2.0)
                if s.recv(256):
                    return True
        time.sleep(0.05)
    return False


PORTS = (30004, 29999, 30001, 30002, 30003, 30020)


def free_loopback_hosts(rng) -> list[str]:
    """127.0.0.x addresses (x in 100-250, shuffled) on which every stand-in port is free now."""
    xs = list(range(100, 251))
    rng.shuffle(xs)
    out = []
    for x in xs:
        host = f"127.0.0.{x}"
        socks = []
        try:
            for port in PORTS:
                sk = socket.socket()
                socks.append(sk)
                sk.bind((host, port))
            out.append(host)
        except OSError:
            pass
        finally:
            for sk in socks:
                sk.close()
        if len(out) >= 5:
            break
    return out


class StandIn:
    """`python -m sim.ursim` in a subprocess on a free loopback address; always killed by `stop()`.

    The address is picked at random among free ones (other test runs may use the same machine at
    the same time); the stand-in counts as started only when *its own* process reports ready, and
    another address is tried if it could not bind. `host`: this address only (one picked free
    earlier, e.g. named in a cell file).
    """

    def __init__(self, *args: str, log: Path, host: str | None = None):
        import random

        self.log = log
        for host in [host] if host else free_loopback_hosts(random.Random()):
            self.host = host
            with open(log, "w") as out:
                self.proc = subprocess.Popen([sys.executable, "-m", "sim.ursim", "--host", host, *args],
                                             stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, cwd=ROOT)
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and self.proc.poll() is None:
                if f"ursim: ready on {host}" in self.log_text():
                    return
                time.sleep(0.05)
            self.stop()
        raise RuntimeError(f"stand-in did not start: {self.log_text()[-2000:]}")

    def log_text(self) -> str:
        return self.log.read_text() if self.log and self.log.exists() else ""

    def admin(self, line: str) -> dict:
        from sim.ursim.admin import admin_request

        assert self.proc.poll() is None, f"the stand-in exited: {self.log_text()[-2000:]}"
        return admin_request(self.host, line)

    def state(self) -> dict:
        return self.admin("state")["state"]

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)


def demo_toolpath(n_fold: int = 56, r_max: float = 0.01):
    """A toolpath in the test bench cell: home (movej), approach (movej), a blended movel curve of
    `n_fold` waypoints over the fixture from grip to release (tool output 0 closes the gripper),
    retract (movel), home (movej)."""
    from robot import kinematics as K
    from robot.cell import load_cell, matrix_to_pose, pose_to_matrix
    from robot.motion import blend_radii
    from robot.toolpath import Toolpath

    cell = load_cell(CELL)
    model = cell.model
    tcp = cell.tool.tcp
    home = np.asarray(cell.robot.home, dtype=np.float64)
    T_home = K.fk_tcp(model, home, tcp)
    p_home = matrix_to_pose(T_home)
    poses, moves, ops = [p_home], ["movej"], ["home"]
    approach = p_home + np.array([0.05, -0.08, -0.06, 0, 0, 0])
    poses.append(approach)
    moves.append("movej")
    ops.append("approach")
    for i in range(n_fold):
        t = i / (n_fold - 1)
        d = np.array([0.05 + 0.12 * np.sin(np.pi * t), -0.08 + 0.16 * t, -0.06 + 0.03 * np.sin(2 * np.pi * t),
                      0, 0, 0])
        T = pose_to_matrix(p_home + d)
        # tilt the tool a little along the curve (the fold rotates the gripped face)
        c, s = np.cos(0.2 * t), np.sin(0.2 * t)
        T[:3, :3] = T[:3, :3] @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
        poses.append(matrix_to_pose(T))
        moves.append("movel")
        ops.append("grip" if i == 0 else "release" if i == n_fold - 1 else "fold")
    retract = poses[-1] + np.array([0, 0, 0.05, 0, 0, 0])
    poses += [retract, p_home]
    moves += ["movel", "movej"]
    ops += ["retract", "home"]
    P = np.array(poses)
    stops = np.array([m == "movej" for m in moves])
    stops[1] = stops[2] = stops[1 + n_fold] = True
    r = blend_radii(P[:, :3], stops, r_max)
    q_prev, wps = home, []
    for i, (p, mv) in enumerate(zip(P, moves)):
        sols = K.ik(model, pose_to_matrix(p), tcp)
        q = K.select_nearest(sols, q_prev, model=model)
        q_prev = q
        lin = mv == "movel"
        wps.append({"pose": [float(x) for x in p], "q": [float(x) for x in q], "move": mv,
                    "v": 0.4 if lin else 1.5, "a": 2.0 if lin else 3.0, "r": float(r[i]), "state": 0,
                    "op": ops[i]})
    grip = {"output": 0, "kind": "tool", "grip_dwell_s": 0.2, "release_dwell_s": 0.2}
    return Toolpath(robot=model.name, cell=cell.name, tcp=tuple(matrix_to_pose(tcp)), source={"test": "demo"},
                    waypoints=tuple(wps), extra={"grip": grip}, cell_sha256=cell.sha256)


def check_report(tp) -> dict:
    """The real MuJoCo check of `tp` in the test bench cell, as CHECK.json data."""
    from robot.cell import load_cell
    from sim.check import check_toolpath

    return check_toolpath(tp, load_cell(CELL)).to_json()


def write_job(tmp: Path, tp, check: dict | None = None) -> tuple[Path, Path]:
    path, chk = tmp / "PATH.json", tmp / "CHECK.json"
    tp.save(path)
    chk.write_text(json.dumps(check if check is not None else check_report(tp)))
    return path, chk


def run_fabkit(*args: str, timeout: float = 120.0, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fabkit", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, **(env or {})})


def move_to(host: str, q, *, timeout: float = 30.0) -> None:
    """Move the arm to joints `q` with the real ur_rtde control interface (test set-up)."""
    import rtde_control

    ctrl = rtde_control.RTDEControlInterface(host, -1.0, rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT,
                                             50002, -1)
    try:
        assert ctrl.moveJ([float(x) for x in q], 1.5, 3.0), "set-up move failed"
        ctrl.stopScript()
    finally:
        ctrl.disconnect()


def standin_fixture(*args: str, unlock_delay: str = "0.2", external_ok: bool = False):
    """A module-scoped pytest fixture that runs one stand-in (`StandIn(*args)`) and always stops it.

    external_ok: with FABKIT_UR_HOST set, the fixture yields None (the tests then use that host).
    """
    import pytest

    @pytest.fixture(scope="module")
    def standin(tmp_path_factory):
        if external_ok and external_host():
            yield None
            return
        s = StandIn(*args, "--unlock-delay", unlock_delay, log=tmp_path_factory.mktemp("ursim") / "ursim.log")
        try:
            yield s
        finally:
            s.stop()

    return standin


def demo_job_fixture():
    """A module-scoped pytest fixture: the demo toolpath, its PATH.json and its real CHECK.json
    (`(toolpath, path, check)`), written once per test module."""
    import pytest

    @pytest.fixture(scope="module")
    def job(tmp_path_factory):
        tp = demo_toolpath()
        path, check = write_job(tmp_path_factory.mktemp("job"), tp)
        assert json.loads(check.read_text())["ok"], "the demo toolpath must pass the real check"
        return tp, path, check

    return job

