"""What the controller receives is what was checked: the stand-in records every motion and tool
command it receives during `fabkit send` of the demo toolpath (admin `record`), and the record is
compared with the checked toolpath waypoint by waypoint.

Two routes carry numbers: ur_rtde's register protocol (setTcp, the final moveJ) carries doubles,
compared bit for bit; its movePath injects the path into the control script as text printed with
6 significant digits (iostream's default), so every path number must equal that printing of the
checked value exactly, and so lie within half a unit of its 6th significant digit of it
(|x_sent - x| <= 5e-6 |x|, with the bound of the printed exponent)."""
import math

import pytest

from _ursim import CELL, demo_toolpath, external_host, standin_fixture, write_job
from fabkit.cli import main as fabkit_main

pytestmark = [pytest.mark.network, pytest.mark.skipif(external_host() is not None,
                                                      reason="the command record is the stand-in's")]

standin = standin_fixture("--cell", str(CELL), unlock_delay="1")


def printed(x: float) -> float:
    """ur_rtde's path printing of x (C++ iostream default precision: 6 significant digits)."""
    return float(f"{x:.6g}")


def six_digit_bound(x: float) -> float:
    """Half a unit of the 6th significant digit of x: the most the printing can move it."""
    return 0.0 if x == 0 else 0.5 * 10.0 ** (math.floor(math.log10(abs(x))) - 5)


def _same_printed(sent, checked) -> bool:
    return all(s == printed(c) and abs(s - c) <= six_digit_bound(c) * (1 + 1e-12) for s, c in zip(sent, checked))


@pytest.fixture(scope="module")
def sent(standin, tmp_path_factory):
    tp = demo_toolpath()
    path, check = write_job(tmp_path_factory.mktemp("job"), tp)
    assert standin.admin("record clear")["ok"]
    rc = fabkit_main(["send", str(path), "--check", str(check), "--cell", str(CELL), "--host", standin.host, "--quiet"])
    assert rc == 0, standin.log_text()[-2000:]
    return tp, standin.admin("record")["commands"]


def test_every_path_waypoint_is_the_checked_one(sent):
    tp, rec = sent
    wps = tp.waypoints
    path = [c for c in rec if c["source"] == "path"]
    assert path, "no movePath waypoint reached the stand-in"
    i = 0  # next toolpath waypoint to find; a chunk starts on the waypoint the previous one ended on
    for c in path:
        key = "q" if c["command"] == "movej" else "pose"
        matches = [k for k in (i, i - 1) if 0 <= k < len(wps) and wps[k]["move"] == c["command"]
                   and _same_printed(c[key], wps[k][key])]
        assert matches, f"recorded {c['command']} {c[key]} is neither waypoint {i} nor {i - 1} as printed"
        k = matches[0]
        w = wps[k]
        assert c["v"] == printed(w["v"]) and c["a"] == printed(w["a"])
        assert 0.0 <= c["r"] <= printed(w["r"])  # blends are only ever shrunk (rounding, chunk ends at rest)
        if k == i:
            i += 1
    assert i == len(wps), f"waypoints {i}-{len(wps) - 1} never reached the controller"


def test_register_commands_are_bit_for_bit(sent):
    tp, rec = sent
    reg = [c for c in rec if c["source"] == "register"]
    tcp = [c for c in reg if c["command"] == "setTcp"]
    assert tcp and all(c["pose"] == list(tp.tcp) for c in tcp)
    last = tp.waypoints[-1]
    final = [c for c in reg if c["command"] in ("moveJ", "moveL")][-1]
    key = "q" if last["move"] == "movej" else "pose"
    assert final["command"] == ("moveJ" if key == "q" else "moveL")
    assert final[key] == list(last[key])  # bit for bit (JSON round-trips doubles exactly)
    assert final["v"] == last["v"] and final["a"] == last["a"]
    assert not [c for c in reg if c["command"] in ("moveJ_IK", "moveL_FK")]


def test_gripper_commands_come_at_grip_and_release(sent):
    tp, rec = sent
    grip = tp.extra["grip"]
    assert grip["kind"] == "tool"
    tool = [(n, c) for n, c in enumerate(rec) if c["command"] == "set_tool_digital_output"]
    assert [c["value"] & (1 << grip["output"]) for _, c in tool] == [0, 1 << grip["output"], 0]
    assert all(c["mask"] == 1 << grip["output"] for _, c in tool)
    ops = [w["op"] for w in tp.waypoints]
    k_grip, k_release = ops.index("grip"), ops.index("release")
    path_pos = [(n, c) for n, c in enumerate(rec) if c["source"] == "path"]

    def first_index_of(k):
        w = tp.waypoints[k]
        key = "q" if w["move"] == "movej" else "pose"
        return next(n for n, c in path_pos if c["command"] == w["move"] and _same_printed(c[key], w[key]))

    # closed after the path reached the grip waypoint and before the move away from it
    assert first_index_of(k_grip) < tool[1][0] < first_index_of(k_grip + 1)
    assert first_index_of(k_release) < tool[2][0] < first_index_of(k_release + 1)


def test_record_is_bounded_and_clearable(standin):
    from sim.ursim.controller import RECORD_MAX

    assert RECORD_MAX <= 100000
    assert standin.admin("record clear")["ok"] and standin.admin("record")["commands"] == []
    assert standin.admin("record everything")["ok"] is False


def test_the_comparison_catches_a_changed_number():
    w = 0.123456789
    assert _same_printed([printed(w)], [w]) and not _same_printed([printed(w) + 1e-6], [w])
    assert not _same_printed([w], [w + 1e-5])
