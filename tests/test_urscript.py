"""URScript writer: full-precision numbers, program structure, no injection from hostile names."""
import math
import re

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fabkit.frames import middle_row_frames
from fold_fixtures import folded_grid_model
from robot.cell import load_cell
from robot.toolpath import Toolpath, plan_panel
from robot.urscript import format_number, sanitise_comment, sanitise_identifier, write_urscript

CELLS = Path(__file__).resolve().parent.parent / "cells"
NUMBER = re.compile(r"(?<![A-Za-z0-9_.])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


@pytest.fixture(scope="module")
def toolpath() -> Toolpath:
    ff = middle_row_frames(folded_grid_model(n_states=6, angles=[math.radians(50)] * 2))
    return plan_panel(load_cell(CELLS / "ur5e_bench.toml"), ff, source={"file": "grid.fold", "sha256": "ab" * 32}).toolpath


def _statements(text):
    return [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("#")]


def test_numbers_read_back_exactly(toolpath):
    text = write_urscript(toolpath)
    moves = [ln for ln in _statements(text) if ln.startswith(("movej", "movel"))]
    assert len(moves) == len(toolpath)
    for ln, w in zip(moves, toolpath.waypoints):
        nums = [float(x) for x in NUMBER.findall(ln)]
        target = w["q"] if ln.startswith("movej") else w["pose"]
        assert nums == list(target) + [w["a"], w["v"], w["r"]]  # bit-exact
        assert ("movej" if w["move"] == "movej" else "movel") == ln[:5]
    # no value rounded to fewer than 12 significant digits: every literal is the exact double
    code = "\n".join(_statements(text))  # comments hold hashes, whose hex digits are not numbers
    for tok in NUMBER.findall(code):
        assert "e" not in tok.lower()
    values = np.concatenate([w["q"] if w["move"] == "movej" else w["pose"] for w in toolpath.waypoints])
    printed = {float(t) for t in NUMBER.findall(text)}
    for v in values:
        assert v in printed
    inexact = [v for v in values if abs(v) > 1e-3 and float(f"{v:.11g}") != v]
    assert inexact, "the test needs values that 11 significant digits cannot hold"


def test_program_structure(toolpath):
    text = write_urscript(toolpath, progress_register=7)
    st_ = _statements(text)
    assert st_[0] == "def fabkit_fold_ur5e_bench():" and st_[-1] == "end"
    assert sum(s.startswith("def ") for s in st_) == 1 and st_.count("end") == 1
    assert st_[1].startswith("set_tcp(p[0.0, 0.0, 0.13, 0.0, 0.0, 0.0])")
    regs = [s for s in st_ if s.startswith("write_output_integer_register(7,")]
    assert len(regs) == len(toolpath) + 1 and regs[-1] == f"write_output_integer_register(7, {len(toolpath)})"
    on = st_.index("set_tool_digital_out(0, True)")
    off = st_.index("set_tool_digital_out(0, False)", on)
    assert st_[on - 1].startswith("movel(") and st_[on + 1] == "sleep(0.5)" and off > on
    assert text.startswith("def fabkit_fold_ur5e_bench():\n  # fabkit fold program")
    header = text.splitlines()[:10]
    assert any(toolpath.sha256 in h for h in header) and any("ab" * 32 in h for h in header)
    assert any("units: metres, radians, seconds" in h for h in header)
    std = write_urscript(toolpath, grip_output=2, grip_output_kind="standard")
    assert "set_standard_digital_out(2, True)" in std and "set_tool_digital_out" not in std


def test_format_number():
    for x in (0.1 + 0.2, 1e-7, -3.141592653589793, 12345.678901234567, 2.0**-40, 7e21):
        s = format_number(x)
        assert float(s) == x and "e" not in s.lower() and "." in s
    assert format_number(0.0) == "0.0" and format_number(-0.0) == "0.0"
    with pytest.raises(ValueError):
        format_number(float("nan"))


ALLOWED = re.compile(
    r"^(def [A-Za-z][A-Za-z0-9_]*\(\):"
    r"|end"
    r"|set_tcp\(p\[[-0-9., ]+\]\)"
    r"|set_(tool|standard)_digital_out\(\d+, (True|False)\)"
    r"|write_output_integer_register\(\d+, \d+\)"
    r"|sleep\([0-9.]+\)"
    r"|movej\(\[[-0-9., ]+\], a=[0-9.]+, v=[0-9.]+, r=[0-9.]+\)"
    r"|movel\(p\[[-0-9., ]+\], a=[0-9.]+, v=[0-9.]+, r=[0-9.]+\))$")


def _assert_no_injection(text):
    for raw in text.split("\n")[:-1]:
        line = raw.strip()
        assert "\r" not in raw and "\x0b" not in raw and "\x0c" not in raw
        if line.startswith("#"):
            continue
        assert ALLOWED.match(line), repr(line)
    assert text.endswith("end\n")


def _moves(tp, cache={}):
    if tp.sha256 not in cache:
        cache[tp.sha256] = [ln for ln in _statements(write_urscript(tp)) if ln.startswith("move")]
    return cache[tp.sha256]


@settings(max_examples=120, deadline=None)
@given(cell=st.text(max_size=60), file=st.text(max_size=60), sha=st.text(max_size=80),
       program=st.one_of(st.none(), st.text(max_size=60)), face=st.text(max_size=20))
def test_hostile_names_cannot_inject(toolpath, cell, file, sha, program, face):
    tp = Toolpath(robot=toolpath.robot, cell=cell, tcp=toolpath.tcp,
                  source={"file": file, "sha256": sha, "grip_face": face, "states": "\nend\nmovej("},
                  waypoints=toolpath.waypoints, extra=toolpath.extra)
    text = write_urscript(tp, program_name=program)
    _assert_no_injection(text)
    # and the motion is unchanged
    assert [ln for ln in _statements(text) if ln.startswith("move")] == _moves(toolpath)


@pytest.mark.parametrize("name", ["x():\n  popup(1)\nend\ndef y", "ä\u2028b", "", "123", "__", "a" * 200,
                                  "#\r\nsocket_open()"])
def test_sanitisers(name):
    ident = sanitise_identifier(name)
    assert re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,42}", ident), ident
    comment = sanitise_comment(name)
    assert re.fullmatch(r"[A-Za-z0-9 _.,:;/=+()\[\]-]*", comment) and len(comment) <= 120


def test_bad_arguments(toolpath):
    with pytest.raises(ValueError):
        write_urscript(toolpath, progress_register=48)
    with pytest.raises(ValueError):
        write_urscript(toolpath, grip_output_kind="analog")
