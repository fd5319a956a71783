"""The vacuum pad's known answers: holding force and the ring-lip tilt capacity of one cup (the
sheet-metal reference's F D / 4) and of a 2 x 2 pad (worked by hand), the moment of resistance
about a crease at a lever arm, the cell's `[tool.pad]`, and the load check's `cup tilt`."""
import math
from pathlib import Path

import numpy as np
import pytest

from fabkit.errors import InputError
from fabkit.sheet.loads import FoldMoment, VacuumCup
from fabkit.sheet.pad import CupPad, single_cup_pad
from robot.cell import parse_cell
from robot.loads import CreaseLoad, arm_rating, check_fold_loads, pad_of_cell

CELLS = Path(__file__).resolve().parent.parent / "cells"


def test_one_50_mm_cup_at_60_kpa():
    pad = single_cup_pad(VacuumCup(0.05))
    F = 60e3 * math.pi * 0.05 ** 2 / 4                                   # 117.8 N
    assert F == pytest.approx(117.81, abs=0.01)
    assert pad.usable_force == pytest.approx(F / 2.5, rel=1e-12)         # 47.1 N
    assert pad.usable_tilt == pytest.approx(F * 0.05 / 4 / 2.5, rel=1e-12)  # 0.589 N m (reference: 1.5 / S)
    # about a crease 0.2 m away: q (pi D d^2 + pi R^3) / (d + R) = F_u (d^2 + R^2 / 2) / (d + R)
    d, R = 0.2, 0.025
    assert pad.moment_capacity(d) == pytest.approx(F / 2.5 * (d * d + R * R / 2) / (d + R), rel=1e-12)


def test_a_2x2_pad_of_50_mm_cups_100_mm_apart():
    pad = CupPad(np.array([[-0.05, -0.05], [0.05, -0.05], [0.05, 0.05], [-0.05, 0.05]]), 0.05)
    q = 60e3 * math.pi * 0.05 ** 2 / 4 / 2.5 / (math.pi * 0.05)            # 300 N/m of lip
    inertia = 4 * (math.pi * 0.05 * 0.05 ** 2 + math.pi * 0.025 ** 3)      # same about any axis in the plane
    assert pad.moment_capacity(0.0, angle=0.0) == pytest.approx(q * inertia / 0.075, rel=1e-12)   # 7.07 N m
    assert pad.usable_tilt == pytest.approx(q * inertia / (0.05 * math.sqrt(2) + 0.025), rel=1e-12)  # 5.54, diagonal
    assert pad.usable_force == pytest.approx(188.50, abs=0.01)            # 4 x 47.12 N
    assert pad.footprint_radius == pytest.approx(0.05 * math.sqrt(2) + 0.025)


def _cell(pad_toml: str):
    import tomllib

    data = tomllib.loads((CELLS / "ur5e_bench.toml").read_text())
    data["tool"]["pad"] = tomllib.loads(pad_toml)["tool"]["pad"]
    return parse_cell(data, source="pad.toml")


def test_a_cell_without_a_pad_holds_with_its_suction_cup():
    from robot.cell import load_cell

    for name in ("ur5e_bench", "ur10e_fold_table"):
        cell = load_cell(CELLS / f"{name}.toml")
        pad = pad_of_cell(cell)
        assert pad.count == 1 and pad.diameter == pytest.approx(0.05) and pad.footprint_radius == pytest.approx(0.025)
        assert pad.diameter == pytest.approx(2 * cell.tool.cup_radius)   # one cup: the footprint's and the loads'
    # the lip the cell declares is the cup, not its holder's collision shape
    text = (CELLS / "ur5e_bench.toml").read_text().replace("cup_radius = 0.025 ", "cup_radius = 0.035 ")
    assert "cup_radius = 0.035 " in text
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "cup70.toml"
        path.write_text(text)
        assert pad_of_cell(load_cell(path)).diameter == pytest.approx(0.07)


def test_cell_pad_table_and_its_mistakes():
    cell = _cell("[tool.pad]\ncup_diameter = 0.05\ncups = [[-0.06, 0.0], [0.06, 0.0]]\n")
    pad = pad_of_cell(cell)
    assert pad.count == 2 and pad.vacuum == 60e3 and pad.safety == 2.5
    with pytest.raises(InputError, match="tool.pad.cups: two cups 40.0 mm apart overlap"):
        _cell("[tool.pad]\ncup_diameter = 0.05\ncups = [[-0.02, 0.0], [0.02, 0.0]]\n")
    with pytest.raises(InputError, match="tool.pad.colour: unknown key"):
        _cell("[tool.pad]\ncup_diameter = 0.05\ncups = [[0.0, 0.0]]\ncolour = 1\n")


def test_the_load_check_fails_the_tilt_and_names_a_bigger_pad():
    arm = arm_rating("ur5e")
    one = single_cup_pad(VacuumCup(0.05))
    load = CreaseLoad(FoldMoment("crease 0", 0.6, 9.0, 10.0), lever=0.1, pull=True)
    rep = check_fold_loads([[], [load]], arm, one.cup, payload_mass=0.0, pad=one)
    tilt = [v for v in rep.verdicts if v.check == "cup tilt"]
    assert len(tilt) == 1 and tilt[0].state == 1 and not tilt[0].ok
    assert tilt[0].capacity == pytest.approx(one.moment_capacity(0.1)) and tilt[0].demand == 10.0
    assert "a bigger pad" in tilt[0].remedy and "two arms" in tilt[0].remedy and "bigger arm" not in tilt[0].remedy
    wide = CupPad(np.array([[-0.06, 0.0], [0.06, 0.0]]), 0.08)
    rep = check_fold_loads([[], [load]], arm, wide.cup, payload_mass=0.0, pad=wide)
    assert [v.ok for v in rep.verdicts if v.check.startswith("cup")] == [True, True]
    pushed = CreaseLoad(load.moment, lever=0.1, pull=False)                # a pad in compression: no vacuum check
    rep = check_fold_loads([[], [pushed]], arm, one.cup, payload_mass=0.0, pad=one)
    assert not [v for v in rep.verdicts if v.check.startswith("cup")]


def test_the_pad_footprint_must_lie_on_the_grip_region():
    from fabkit.frames import middle_row_frames
    from fabkit.grip_footprint import FoldGeometry, pad_footprint
    from fold_fixtures import folded_grid_model

    model = folded_grid_model(n_states=3, angles=[math.radians(60)] * 2, triangulate=True)
    geo = FoldGeometry.of_fold(model)
    face = int(middle_row_frames(model).faces[-1])
    small = pad_footprint(geo, face, 0.01, max_bend=math.radians(0.5))
    assert small.ok and small.faces[0] == face and small.inscribed_m >= 0.01
    # a pad wider than the sheet around the face centre is refused, naming the face
    wide = pad_footprint(geo, face, small.inscribed_m + 0.005, max_bend=math.radians(0.5))
    assert not wide.ok and f"does not fit on grip face {face}" in wide.problem
