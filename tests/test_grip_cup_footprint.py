"""The suction cup's footprint on the grip face of a rigid program: measured on the sheet up to the
creases and outline, planar to the lip compliance in every fold state, and reported in CHECK.json
(not a problem of the rigid check)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from holds_panels import reflect_two_crease_pair, trifold_sequence
from refold_panels import reflect_pair

from fabkit.grip_footprint import cup_footprint_record, pad_footprint
from fabkit.refold import refold

ROOT = Path(__file__).resolve().parent.parent
CUP = 0.035     # the cells' 70 mm cup


def _middle(seq):
    mid = np.asarray(seq.face_data["middle"]) != 0
    return sorted(set(np.asarray(seq.face_data["polygon"])[mid].tolist()))


@pytest.fixture(scope="module")
def reflect_one():
    flat, target = reflect_pair(1)
    return refold(flat, target, frames=6)


def test_one_face_is_too_narrow_but_the_sheet_across_the_rulings_is_measured(reflect_one):
    for face in _middle(reflect_one):
        alone = pad_footprint(reflect_one, face, CUP)               # the grip region: hinges under 0.8 deg
        assert not alone.ok and alone.inscribed_m * 2 == pytest.approx(0.0436, abs=5e-4)
        assert "does not fit" in alone.problem
        sheet = pad_footprint(reflect_one, face, CUP, rulings_join=True)
        assert sheet.inscribed_m > CUP                              # the disc lies inside the sheet
        # the sheet under a flat 70 mm lip curves away by 0.95 mm over the fold states (lip: 0.5 mm)
        assert sheet.planarity_m == pytest.approx(0.95e-3, abs=0.05e-3)
        assert not sheet.ok and "leaves its plane by 0.9" in sheet.problem


def test_the_two_crease_panel_and_the_trifold_carry_the_cup():
    flat, target = reflect_two_crease_pair()
    for seq in (refold(flat, target, frames=6), trifold_sequence(6)):
        for face in _middle(seq):
            c = pad_footprint(seq, face, CUP, rulings_join=True)
            assert c.ok and c.inscribed_m > CUP and 0.1e-3 < c.planarity_m < 0.35e-3, (face, c)


def test_the_check_reports_the_cup_on_the_grip_face_and_does_not_refuse_on_it(tmp_path):
    import fabkit.pipeline as fk
    from fabkit.io.obj import save_obj
    from structure_panels import reflect_tagged

    save_obj(reflect_tagged(2, 60.0), tmp_path / "p.obj")
    folds = fk.refold(fk.unfold(fk.relax(fk.load(tmp_path / "p.obj"))), frames=5)
    text = (ROOT / "cells" / "ur5e_bench.toml").read_text()
    assert "cup_radius = 0.035" in text
    small = tmp_path / "small_cup.toml"
    small.write_text(text.replace("cup_radius = 0.035", "cup_radius = 0.02"))   # a 40 mm cup
    # the 70 mm lip: the sheet curves away by 0.95 mm; the 40 mm lip lies on the grip face itself
    # (43.6 mm across), which is planar
    for cell, fits in ((ROOT / "cells" / "ur5e_bench.toml", False), (small, True)):
        check = fk.check(fk.plan(folds, str(cell), workdir=tmp_path / cell.stem))
        assert check.ok, check.problems                           # reported, not enforced
        rec = check.report.holds["cup_footprint"]
        assert rec["enforced"] is False and rec["cup_mm"] == pytest.approx(70.0 if not fits else 40.0)
        (row,) = rec["faces"]
        assert row["ok"] is fits and row["room_mm"] > rec["cup_mm"]
        assert row["planarity_mm"] == pytest.approx(0.95, abs=0.05) if not fits else row["planarity_mm"] < 1e-6
        notes = [n for n in check.report.notes if n.startswith(f"grip face {row['face']}:")]
        assert bool(notes) is not fits
        if not fits:
            assert "leaves its plane by 0.95 mm" in notes[0] and "does not refuse on it" in notes[0]


def test_no_cup_in_the_cell_or_no_grip_no_record():
    assert cup_footprint_record(None, {"arms": {"a": [1, None]}}, None) == (None, ())
    assert cup_footprint_record(None, {"arms": {"a": [None, None]}}, CUP) == (None, ())
