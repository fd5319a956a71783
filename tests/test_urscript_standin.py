"""The URScript program runs on the controller stand-in (sim/ursim): sent as text to the secondary
script port like to a real controller, it compiles, switches the gripper on and off, reports
progress in its output register and ends back at home.

`FABKIT_UR_HOST` would point this at a real URSim; loopback only otherwise.
"""
import math
import socket
import time
from pathlib import Path

import numpy as np
import pytest

from _ursim import StandIn, external_host
from fabkit.frames import middle_row_frames
from fold_fixtures import folded_grid_model
from robot.cell import load_cell
from robot.motion import MotionParams
from robot.toolpath import PlanOptions, plan_panel
from robot.urscript import PROGRESS_REGISTER, write_urscript
from sim.ursim.urscript import parse_program

CELL = Path(__file__).resolve().parent.parent / "cells" / "ur5e_bench.toml"
TOOL_BIT = 1 << 16  # the stand-in's digital_out word: tool outputs from bit 16


@pytest.fixture(scope="module")
def program():
    cell = load_cell(CELL)
    ff = middle_row_frames(folded_grid_model(n_states=3, angles=[math.radians(20)] * 2))
    fast = MotionParams(joint_speed=3.0, joint_accel=3.0, approach_speed=0.25, retract_speed=0.25, fold_speed=0.25,
                        tcp_accel=1.2, grip_dwell=0.2, release_dwell=0.2)
    tp = plan_panel(cell, ff, options=PlanOptions(approach_distance=0.03, params=fast)).toolpath
    return tp, write_urscript(tp)


def test_stand_in_compiles_the_program(program):
    tp, text = program
    name, statements = parse_program(text)
    assert name == "fabkit_fold_ur5e_bench"
    assert sum(s.name in ("movej", "movel") for s in statements) == len(tp)


@pytest.mark.network
def test_program_runs_on_the_stand_in(program, tmp_path):
    if external_host():
        pytest.skip("runs a fold program only on the loopback stand-in")
    tp, text = program
    cell = load_cell(CELL)
    standin = StandIn("--cell", str(CELL), log=tmp_path / "ursim.log")  # a free loopback address; cell home
    try:
        with socket.create_connection((standin.host, 30002), timeout=5.0) as s:
            s.sendall(text.encode("ascii"))
        seen_grip, progress, deadline = False, [], time.monotonic() + 90.0
        while time.monotonic() < deadline:
            st = standin.state()
            assert not st["last_error"], st["last_error"]
            progress.append(st["out_int"][PROGRESS_REGISTER])
            seen_grip |= bool(st["digital_out"] & TOOL_BIT)
            if progress[-1] == len(tp):  # written after the last move has finished
                break
            time.sleep(0.05)
        else:
            pytest.fail(f"program did not finish; progress {progress[-5:]}; log {standin.log_text()[-1500:]}")
        st = standin.state()
        np.testing.assert_allclose(program[0].waypoints[0]["q"], cell.robot.home)
        assert seen_grip and not st["digital_out"] & TOOL_BIT   # gripped, then released
        assert progress == sorted(progress) and progress[-1] == len(tp)
        np.testing.assert_allclose(st["q"], tp.waypoints[-1]["q"], atol=1e-6)
    finally:
        standin.stop()
