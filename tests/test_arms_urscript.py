"""The two-arm handshake's bounded wait as the controller stand-in compiles it
(`sim.ursim.script_waits`): the form `robot.arms_urscript` writes is one wait statement with its
time-out and its halt; a time-out body that does not halt, runs something else, or a loop without
its `end` is refused naming the line, as a controller refuses a program that does not compile."""
from __future__ import annotations

import pytest

from robot.arms_urscript import handshake_lines
from sim.ursim.urscript import ScriptError, parse_program


def _program(lines) -> str:
    return "def p():\n" + "".join(f"  {ln}\n" for ln in lines) + "end\n"


def test_the_written_bounded_wait_is_one_statement_with_its_timeout_and_halt():
    lines = handshake_lines(True, 6, 5, timeout_s=2.25, previous=False, message='arm a at sync 7 "; halt')
    name, sts = parse_program(_program(lines))
    assert name == "p" and [s.name for s in sts] == ["set_standard_digital_out", "wait_standard_digital_in"]
    wait = sts[1]
    assert wait.args == (5, True) and wait.kwargs["timeout"] == 2.25
    assert [s.name for s in wait.kwargs["then"]] == ["set_standard_digital_out", "stopj", "textmsg", "popup", "halt"]
    assert wait.kwargs["then"][0].args == (6, False)
    assert wait.kwargs["then"][3].args == ("arm a at sync 7 _; halt",)  # the quote cannot end the string
    name, sts = parse_program(_program(handshake_lines(False, 6, 6)))  # the unbounded form
    assert sts[1].args == (6, False) and "timeout" not in sts[1].kwargs
    with pytest.raises(ValueError, match="not a positive"):
        handshake_lines(True, timeout_s=0.0)


@pytest.mark.parametrize("edit, match", [
    (lambda L: [ln for ln in L if ln.strip() != "halt"], "must end with 'halt'"),
    (lambda L: [ln.replace("stopj(2.0)", "movej([0, 0, 0, 0, 0, 0])") for ln in L], r"line \d+: movej\(\) is not supported"),
    (lambda L: L[:-1], "no closing 'end'"),
    (lambda L: [ln.replace("> 3.0:", ">= 3.0:") for ln in L], r"line \d+: the time-out test must be"),
])
def test_a_malformed_bounded_wait_is_refused_naming_the_line(edit, match):
    lines = edit(handshake_lines(True, timeout_s=3.0, previous=False, message="m"))
    with pytest.raises(ScriptError, match=match):
        parse_program(_program(lines))


@pytest.mark.parametrize("value", ["-1", "0", "nan"])
def test_fabkit_toolpath_refuses_a_handshake_timeout_that_is_not_a_positive_time(value, tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    r = subprocess.run([sys.executable, "-m", "fabkit", "toolpath", str(root / "tests" / "data" / "fold" / "pleat-xz.fold"),
                        "--cell", str(root / "cells" / "dual_ur10e.toml"), "-o", str(tmp_path / "p.json"),
                        "--handshake-timeout", value], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--handshake-timeout" in r.stderr and "not a positive time" in r.stderr, r.stderr
    assert not (tmp_path / "p.json").exists()
