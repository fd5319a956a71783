"""The running stand-in (its own process, programs over the secondary interface) times motion as the
planner predicts: the demo program's motion time equals `robot.motion.toolpath_cycle_time` to one
controller period per run, a heavier `set_payload` slows a fast movej by exactly what
`robot.ur_motion.joint_accel_bound` predicts and ends on the same joints, and a payload over the
arm's rating is a runtime error that leaves the payload as it was."""
import socket
import time

import numpy as np
import pytest

from _ursim import CELL, demo_toolpath, external_host, standin_fixture
from robot import ur_motion as U
from robot.loads import arm_rating
from robot.motion import toolpath_cycle_time

pytestmark = [pytest.mark.network, pytest.mark.skipif(external_host() is not None,
                                                      reason="controller time and state need the stand-in")]
PERIOD = 0.002

standin = standin_fixture("--cell", str(CELL))


def _list(q) -> str:
    return "[" + ", ".join(repr(float(x)) for x in q) + "]"


def _run(standin, text: str, timeout: float = 60.0) -> float:
    """Send a program, wait for its end; the controller time (s) the arm was under motion control."""
    st0 = standin.state()
    with socket.create_connection((standin.host, 30002), timeout=5) as s:
        s.sendall(text.encode())
    started = False
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        st = standin.state()
        started = started or st["runtime_state"] == 2 or st["motion_time"] > st0["motion_time"]
        if started and st["runtime_state"] == 1 and st["arm_mode"] == "idle":
            return st["motion_time"] - st0["motion_time"]
        time.sleep(0.005)
    raise AssertionError(f"program did not finish: {standin.state()}")


def test_demo_program_runs_as_long_as_the_planner_says(standin):
    from robot.urscript import write_urscript

    tp = demo_toolpath()
    _run(standin, f"movej({_list(tp.waypoints[0].q)}, a=3.0, v=1.5, r=0)\n")
    motion = _run(standin, write_urscript(tp))
    st = standin.state()
    planned = toolpath_cycle_time(tp).motion
    runs = len(U.run_bounds([w.move for w in tp.waypoints], [w.r for w in tp.waypoints]))
    print(f"\ndemo on the stand-in: motion {motion:.4f} s, planner {planned:.4f} s ({runs} runs)")
    assert not st["last_error"], st["last_error"]
    assert -PERIOD / 2 <= motion - planned <= runs * PERIOD + PERIOD / 2
    assert np.abs(np.array(st["q"]) - tp.waypoints[-1].q).max() < 1e-9


def test_heavier_payload_slows_a_fast_movej_as_predicted(standin):
    home = np.asarray(demo_toolpath().waypoints[0].q)
    swing = home + np.array([0.6, 0.1, -0.1, 0.0, 0.0, 0.0])
    rated = arm_rating("ur5e").payload
    times, ends = {}, {}
    for mass in (0.5, 4.5):
        _run(standin, f"movej({_list(home)}, a=3.0, v=1.5, r=0)\n")
        times[mass] = _run(standin, f"def fast():\n  set_payload({mass}, [0.0, 0.0, 0.05])\n"
                                    f"  movej({_list(swing)}, a=35.0, v=3.0, r=0)\n"
                                    f"  movej({_list(home)}, a=35.0, v=3.0, r=0)\nend\n")
        st = standin.state()
        assert not st["last_error"] and st["payload"] == mass
        ends[mass] = np.array(st["q"])
    # out and back, each a = min(35, bound): 38 rad/s^2 at 0.5 kg (35 used), 22 at 4.5 kg
    a_heavy = U.joint_accel_bound(4.5, rated)
    predicted = 2 * (U.time_law([0.6], [3.0], [a_heavy]).duration - U.time_law([0.6], [3.0], [35.0]).duration)
    print(f"\nfast movej: {times[0.5]:.4f} s at 0.5 kg, {times[4.5]:.4f} s at 4.5 kg "
          f"(+{times[4.5] - times[0.5]:.4f} s, model +{predicted:.4f} s)")
    assert times[4.5] - times[0.5] == pytest.approx(predicted, abs=2 * PERIOD + 1e-9)
    assert np.abs(ends[0.5] - ends[4.5]).max() == 0.0 and np.abs(ends[4.5] - home).max() < 1e-12


def test_payload_over_the_rating_is_a_runtime_error(standin):
    with socket.create_connection((standin.host, 30002), timeout=5) as s:
        s.sendall(b"def light():\n  set_payload(1.0)\nend\n")
    deadline = time.monotonic() + 10
    while standin.state()["payload"] != 1.0 and time.monotonic() < deadline:
        time.sleep(0.02)
    with socket.create_connection((standin.host, 30002), timeout=5) as s:
        s.sendall(b"def heavy():\n  set_payload(6.0, [0.0, 0.0, 0.05])\n  sleep(0.1)\nend\n")
    deadline = time.monotonic() + 10
    while "rated payload" not in (standin.state()["last_error"] or "") and time.monotonic() < deadline:
        time.sleep(0.02)
    st = standin.state()
    assert "exceeds the arm's rated payload of 5 kg" in st["last_error"]
    assert st["payload"] == 1.0
