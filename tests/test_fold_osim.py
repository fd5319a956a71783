"""Every FOLD fabkit writes loads in Origami Simulator: its importer's rules (fabkit.io.fold_compat, read
from its source) checked on each writer's output; J diagonals go out as F and come back as J."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.io.fold import fold_to_json, load_fold, save_fold
from fabkit.io.fold_compat import origami_simulator_problems
from fabkit.io.obj import save_obj
from fabkit.io.save import save_panel
from fabkit.refold import refold
from fabkit.refold.export import to_fold_model
from panel_inputs import plain_obj, reflect
from refold_panels import reflect_pair


def _check(path) -> dict:
    d = json.loads(open(path).read())
    assert origami_simulator_problems(d) == [], path
    assert all(a in "UVMBFC" for a in d["edges_assignment"])
    # frame_attributes match the content: 2D exactly when every z is 0
    for frame in [d] + d.get("file_frames", []):
        coords = np.array(frame.get("vertices_coords", d["vertices_coords"]), dtype=float)
        dim = "2D" if np.all(coords[:, 2] == 0) else "3D"
        assert dim in frame["frame_attributes"] and ({"2D", "3D"} - {dim}).isdisjoint(frame["frame_attributes"])
    return d


def test_rules_catch_what_the_importer_rejects():
    good = {"vertices_coords": [[0, 0], [1, 0], [0, 1]], "edges_vertices": [[0, 1], [1, 2], [2, 0]],
            "edges_assignment": ["B", "B", "B"], "faces_vertices": [[0, 1, 2]], "edges_foldAngle": [0, 0, None]}
    assert origami_simulator_problems(good) == []
    assert "J" in origami_simulator_problems({**good, "edges_assignment": ["B", "J", "B"]})[0]
    assert "'b'" in origami_simulator_problems({**good, "edges_assignment": ["b", "B", "B"]})[0]
    assert origami_simulator_problems({k: v for k, v in good.items() if k != "faces_vertices"}) == \
        ["missing faces_vertices"]
    assert "edges_foldAngle[0]" in origami_simulator_problems({**good, "edges_foldAngle": [200, 0, 0]})[0]
    assert "faces_vertices[0]" in origami_simulator_problems({**good, "faces_vertices": [[0, 1, 7]]})[0]
    assert "one entry per edge" in origami_simulator_problems({**good, "edges_foldAngle": [0]})[0]


def test_refold_output_writes_diagonals_as_F_and_reads_them_back_as_J(tmp_path):
    flat, target = reflect_pair(1, columns=6, rows=2)
    seq = refold(flat, target, frames=3)
    model = to_fold_model(seq)
    assert np.any(model.edges_assignment == "J")
    save_fold(model, tmp_path / "seq.fold")
    d = _check(tmp_path / "seq.fold")
    joins = np.array(d["edges_fabkit:join"]) == 1
    assert joins.sum() == np.sum(model.edges_assignment == "J")
    assert set(np.array(d["edges_assignment"])[joins]) == {"F"}
    back = load_fold(tmp_path / "seq.fold")
    np.testing.assert_array_equal(back.edges_assignment, model.edges_assignment)
    assert "join" not in back.edges_data
    spec = fold_to_json(model, flavour="spec")
    assert "J" in spec["edges_assignment"] and "edges_fabkit:join" not in spec
    assert "joins" in spec["frame_attributes"]
    with pytest.raises(ValueError, match="flavour"):
        fold_to_json(model, flavour="osim")


def test_every_command_that_writes_fold_passes(tmp_path, capsys):
    V, F = reflect(columns=8, rows=2)
    plain_obj(tmp_path / "p.obj", V, F)
    assert main(["relax", str(tmp_path / "p.obj"), "-o", str(tmp_path / "r.fold"), "-q"]) == 0
    _check(tmp_path / "r.fold")
    assert main(["unfold", str(tmp_path / "p.obj"), "-o", str(tmp_path / "flat.fold"), "-q"]) == 0
    d = _check(tmp_path / "flat.fold")
    assert len(d["file_frames"]) == 1 and "V" in d["edges_assignment"]
    flat, target = reflect_pair(2, columns=8, rows=2)  # tagged: refold finds its drive
    save_obj(flat, tmp_path / "flat.obj")
    save_obj(target, tmp_path / "target.obj")
    assert main(["refold", str(tmp_path / "flat.obj"), str(tmp_path / "target.obj"), "-o", str(tmp_path / "seq.fold"),
                 "--frames", "3", "-q"]) == 0
    _check(tmp_path / "seq.fold")
    back = load_fold(tmp_path / "seq.fold")
    assert np.any(back.edges_assignment == "J")


def test_panels_fold_passes_and_is_a_two_state_fold(tmp_path):
    from fabkit.frames import fold_positions
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.output import write_run
    from fabkit.panels.surface import canopy_lowpoly, subdivide_grid
    from fabkit.panels.workflow import PanelsOptions, run_panels

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        surface = subdivide_grid(canopy_lowpoly(), 2)
        run = run_panels(layout_panels(surface, rows=2, cols=1, columns_per_panel=4), PanelsOptions(max_rounds=0))
    write_run(run, tmp_path / "out", plots=False, cut_files=False)
    folds = sorted((tmp_path / "out" / "panels").glob("*.fold"))
    assert folds
    for f in folds:
        _check(f)
        model = load_fold(f)
        states = fold_positions(model)
        assert len(states) == 2 and np.all(states[0][:, 2] == 0) and not np.all(states[1][:, 2] == 0)


def test_save_panel_fold_of_flat_and_folded_meshes(tmp_path):
    from fabkit.generate.reflect import reflect_panel

    panel = reflect_panel(columns=6, rows=2)
    save_panel(panel, tmp_path / "p.fold")
    assert _check(tmp_path / "p.fold")["frame_classes"] == ["foldedForm"]
    flat = panel.with_vertices(np.column_stack([panel.vertices[:, :2], np.zeros(panel.n_vertices)]))
    save_obj(flat, tmp_path / "flat.obj")
    save_panel(flat, tmp_path / "f.fold")
    assert _check(tmp_path / "f.fold")["frame_classes"] == ["creasePattern"]
