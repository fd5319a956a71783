"""A plain two-crease 175 deg zigzag (reflection method: a valley and a mountain, no tags) through
relax -> unfold -> refold -> toolpath -> check -> dry-run send on the UR10e fold-table cell, with no
tags, drive file, grip face or unit flag.

Clamped at its mountain end, the zigzag's far strip would travel face up along a U under the clamp
(0.22 m below the panel, 8 cm over the table) and end tucked 19 mm under the clamped strip: the
wrist meets the clamped strip from above, and from below there is no room over the table. The
structure clamps the valley end instead (`fabkit.structure`): the far strip then rides face up over
the panel and ends on top of the stack, and one front grip folds both creases with the holds
proven in every state.
"""
import json
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.io.obj import load_obj, save_obj
from structure_panels import plain, reflect_tagged

CELL = str(Path(__file__).resolve().parent.parent / "cells" / "ur10e_fold_table.toml")


@pytest.mark.slow
def test_a_175_deg_zigzag_is_folded_from_its_valley_end_and_sent(tmp_path):
    from _ursim import StandIn

    from fabkit.io.fold import load_fold
    from fabkit.structure import panel_structure

    tagged = reflect_tagged(2, 175.0)
    p, rel, flat, seq = (tmp_path / n for n in ("panel.obj", "rel.obj", "flat.obj", "seq.fold"))
    save_obj(plain(tagged), p)
    assert main(["relax", str(p), "-o", str(rel), "-q"]) == 0
    assert main(["unfold", str(rel), "-o", str(flat), "-q"]) == 0
    assert main(["refold", str(flat), str(rel), "-o", str(seq), "--frames", "5", "-q"]) == 0

    # the clamped face is on the end strip beside the valley (tagged strip 0: its crease folds +175)
    s = panel_structure(load_obj(rel))
    clamp = int(load_fold(seq).file_data["fabkit:fixed_face"])
    assert clamp == s.clamp_face and int(tagged.face_data["strip"][clamp]) == 0
    end = int(s.strip[clamp])                       # the first or the last strip: its crease row
    near = [e for e in s.middle_creases if int(s.crease_row[e]) == (end if end == 0 else end - 1)]
    assert near and all(np.degrees(s.fold_angle[e]) == pytest.approx(175.0, abs=0.5) for e in near)

    path, report, check = tmp_path / "path.json", tmp_path / "toolpath.json", tmp_path / "check.json"
    assert main(["toolpath", str(seq), "--cell", CELL, "-o", str(path), "--report", str(report), "-q"]) == 0
    doc, grip = json.loads(path.read_text()), json.loads(report.read_text())["grip_face"]
    assert "phases" not in doc and doc["placement"]["clamped_face"] == clamp and grip != clamp
    assert int(tagged.face_data["strip"][grip]) == 2                    # the far end of the row, one grip
    assert main(["check", str(path), "--cell", CELL, "-o", str(check), "-q"]) == 0
    rep = json.loads(check.read_text())
    assert rep["ok"] and rep["holds"]["ok"] and all(st["ok"] for st in rep["holds"]["states"])
    assert rep["panel_collisions"]["ok"]
    assert rep["holds"]["cup_footprint"]["enforced"] and all(f["ok"] for f in rep["holds"]["cup_footprint"]["faces"])

    # the dry run: the same program folded at the cell's TCP limit (the default 0.05 m/s folds for 80 s)
    fast, fast_check = tmp_path / "fast.json", tmp_path / "fast_check.json"
    assert main(["toolpath", str(seq), "--cell", CELL, "-o", str(fast), "--fold-speed", "0.25", "-q"]) == 0
    assert json.loads(fast.read_text())["source"]["grip_face"] == grip
    assert main(["check", str(fast), "--cell", CELL, "-o", str(fast_check), "-q"]) == 0
    standin = StandIn("--cell", CELL, log=tmp_path / "ursim.log")
    try:
        rc = main(["send", str(fast), "--check", str(fast_check), "--cell", CELL, "--host", standin.host,
                   "--power-on", "--report", str(tmp_path / "send.json"), "-q"])
        sent = json.loads((tmp_path / "send.json").read_text())
        n = len(json.loads(fast.read_text())["waypoints"])
        assert rc == 0 and sent["ok"] and sent["last_completed"] == n - 1, sent
    finally:
        standin.stop()


@pytest.mark.parametrize("fold", [60.0, 175.0])
def test_a_zigzag_is_clamped_at_its_valley_end_in_any_order_and_unit(fold):
    """The clamp end is chosen from the fold directions, so shuffled vertices and faces and a
    millimetre copy give the same face (at 175 deg the inferred strip order starts at the mountain
    end, at 60 deg at the valley end: the rule, not the order, decides)."""
    from fabkit.structure import panel_structure
    from structure_panels import shuffled

    tagged = reflect_tagged(2, fold)
    mesh = plain(tagged)
    s = panel_structure(mesh)
    assert int(tagged.face_data["strip"][s.clamp_face]) == 0
    perm, _, _ = shuffled(mesh, seed=4)
    p = panel_structure(perm)
    assert np.allclose(perm.face_centroids[p.clamp_face], mesh.face_centroids[s.clamp_face], atol=1e-12)
    mm = panel_structure(mesh.with_vertices(mesh.vertices * 1000.0))
    assert mm.clamp_face == s.clamp_face
