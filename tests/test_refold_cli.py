"""`fabkit refold` end to end: FOLD written and read back (ours and the npm reference), exit codes."""
import json

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.io.fold import load_fold, save_fold
from fabkit.io.obj import save_obj
from fabkit.mesh import PolyMesh
from fabkit.refold import refold
from fabkit.refold.export import to_fold_model
from refold_panels import reflect_pair


@pytest.fixture(scope="module")
def pair_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("refold")
    flat, target = reflect_pair(2, columns=8, rows=2)
    save_obj(flat, d / "flat.obj")
    save_obj(target, d / "target.obj")
    return d, flat, target


def test_fold_file_reads_back_exactly(tmp_path):
    flat, target = reflect_pair(1, columns=6, rows=2)
    seq = refold(flat, target, frames=4)
    model = to_fold_model(seq)
    path = tmp_path / "seq.fold"
    save_fold(model, path)
    back = load_fold(path)
    np.testing.assert_array_equal(back.vertices_coords, seq.flat_vertices)
    np.testing.assert_array_equal(np.array(back.faces_vertices), seq.tris)
    np.testing.assert_array_equal(back.edges_vertices, seq.edges)
    np.testing.assert_array_equal(back.edges_assignment, seq.edges_assignment)
    np.testing.assert_array_equal(back.edges_fold_angle, seq.target_angles)
    assert back.n_frames == seq.n_states
    for s, frame in enumerate(back.frames):
        np.testing.assert_array_equal(frame.vertices_coords, seq.positions[s])
        np.testing.assert_array_equal(frame.edges_fold_angle, seq.angles[s])
    np.testing.assert_array_equal(back.faces_data["polygon"], seq.tri_face)
    np.testing.assert_array_equal(back.edges_data["crease"], seq.edge_crease)
    assert set(back.edges_data["crease"][seq.edge_kind == "crease"]) == {0}
    assert set(back.edges_data["crease"][seq.edge_kind != "crease"]) == {-1}
    for tag in ("strip", "column", "middle"):
        np.testing.assert_array_equal(back.faces_data[tag], np.asarray(flat.face_data[tag])[seq.tri_face])
    # assignments: J diagonals, B outline, M/V by the target's sign on creases
    kinds = seq.edge_kind
    assert set(back.edges_assignment[kinds == "diagonal"]) == {"J"}
    assert set(back.edges_assignment[kinds == "boundary"]) == {"B"}
    crease = kinds == "crease"
    assert set(back.edges_assignment[crease]) == {"V"} and np.all(seq.target_angles[crease] > 0)


def test_cli_writes_fold_png_glb_report_and_objs(pair_files, tmp_path):
    d, flat, target = pair_files
    out, png, glb, rep = tmp_path / "seq.fold", tmp_path / "a.png", tmp_path / "s.glb", tmp_path / "r.json"
    objs = tmp_path / "objs"
    objs.mkdir()
    rc = main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(out), "--frames", "5",
               "--png", str(png), "--glb", str(glb), "--report", str(rep), "--obj-dir", str(objs), "-q"])
    assert rc == 0
    model = load_fold(out)
    assert model.n_frames == 5 and model.classes == ("creasePattern",)
    report = json.loads(rep.read_text())
    assert report["ok"] and report["format"] == "fabkit.refold/1"
    assert report["summary"]["max_loop_residual_rad"] <= 1e-9
    assert report["summary"]["max_edge_length_error_rel"] <= 1e-9
    assert report["summary"]["target_distance_rel"] <= 1e-6
    assert len(report["states"]) == 5 and report["states"][0]["newton_iterations"] == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import trimesh

    scene = trimesh.load(glb, force="scene")
    assert len(scene.geometry) == 5
    from fabkit.io.obj import load_obj

    last = load_obj(objs / "state_004.obj")
    assert last.n_faces == flat.n_faces and list(last.face_data) == list(flat.face_data)
    np.testing.assert_allclose(last.vertices, model.frames[-1].vertices_coords, atol=1e-12)


def test_fold_satisfies_origami_simulator_and_the_npm_reference(pair_files, tmp_path):
    from test_fold import _cyclic, _read_with_js  # the I/O helper's npm `fold` check

    d, flat, target = pair_files
    out = tmp_path / "seq.fold"
    assert main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(out), "--frames", "3", "-q"]) == 0
    raw = json.loads(out.read_text())
    for key in ("vertices_coords", "edges_vertices", "edges_assignment", "faces_vertices"):  # OS importer
        assert key in raw and raw[key]
    assert set(raw["edges_assignment"]) <= set("BMVFU")
    assert raw["file_classes"] == ["animation"] and len(raw["file_frames"]) == 3
    js = _read_with_js(out)
    model = load_fold(out)
    assert (js["numVertices"], js["numEdges"], js["numFaces"]) == (model.n_vertices, model.n_edges, model.n_faces)
    assert js["faceOrientation"] == [1] * model.n_faces
    assert js["missingFaceSides"] == 0
    written = np.where(model.edges_assignment == "J", "F", model.edges_assignment)  # diagonals go out as F
    assert js["assigned"] == {a: int(np.sum(written == a)) for a in "BMVFJUC"}
    assert sorted(_cyclic(f) for f in js["recoveredFaces"]) == sorted(_cyclic(f) for f in model.faces_vertices)
    assert "faces_fabkit:polygon" in js["facesKeys"] and "faces_fabkit:middle" in js["facesKeys"]
    for fjs, frame in zip(js["frames"], model.frames):
        assert fjs["inherit"] is True and fjs["parent"] == 0
        np.testing.assert_allclose(np.array(fjs["coords"]) / 1000.0, frame.vertices_coords, rtol=0, atol=1e-15)
        np.testing.assert_allclose(np.radians(np.array(fjs["foldAngle"], float)), frame.edges_fold_angle,
                                   rtol=0, atol=1e-15)


def test_target_that_is_not_a_fold_exits_1_naming_the_edge(pair_files, tmp_path, capsys):
    d, flat, target = pair_files
    V = np.array(target.vertices)
    V[7] *= 1.01
    save_obj(PolyMesh(V, target.faces_list(), face_data=target.face_data), tmp_path / "bad.obj")
    out, rep = tmp_path / "seq.fold", tmp_path / "r.json"
    rc = main(["refold", str(d / "flat.obj"), str(tmp_path / "bad.obj"), "-o", str(out), "--report", str(rep)])
    assert rc == 1
    err = capsys.readouterr().err
    assert "not a fold of the flat pattern" in err and "edge (" in err and "7" in err
    assert not out.exists()
    report = json.loads(rep.read_text())
    assert not report["ok"] and 7 in report["worst_edge"]
    # a looser tolerance accepts it (and the last state then misses the target: exit 1, files written)
    rc = main(["refold", str(d / "flat.obj"), str(tmp_path / "bad.obj"), "-o", str(out), "--length-tol", "0.1",
               "--frames", "3", "-q"])
    assert rc == 1 and out.exists()
    assert "from TARGET" in capsys.readouterr().err


@pytest.mark.parametrize("extra, needle", [
    (["--frames", "1"], "--frames"),
    (["--drive", "nope"], "nope"),
    (["--fixed-face", "100000"], "fixed face"),
    (["--steps", "ridge0"], "creaseK"),
    (["--length-tol", "-1"], "--length-tol"),
    (["--glb", "x.png"], ".glb"),
])
def test_bad_usage_exits_2(pair_files, tmp_path, capsys, extra, needle):
    d, _, _ = pair_files
    out = tmp_path / "seq.fold"
    rc = main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(out), *extra])
    assert rc == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_missing_input_and_swapped_inputs_exit_2(pair_files, tmp_path, capsys):
    d, _, _ = pair_files
    assert main(["refold", str(tmp_path / "none.obj"), str(d / "target.obj"), "-o", str(tmp_path / "o.fold")]) == 2
    assert "none.obj" in capsys.readouterr().err
    assert main(["refold", str(d / "target.obj"), str(d / "flat.obj"), "-o", str(tmp_path / "o.fold")]) == 2
    assert "not a flat pattern" in capsys.readouterr().err
    assert not (tmp_path / "o.fold").exists()


def test_cli_drive_file_and_steps(pair_files, tmp_path):
    d, flat, target = pair_files
    from fabkit.refold import RefoldSolver
    from fabkit.refold.sequence import middle_row_hinges

    s = RefoldSolver(flat, target)
    mid = middle_row_hinges(s.panel)
    drive = tmp_path / "drive.json"
    drive.write_text(json.dumps([s.panel.edges[e].tolist() for e in mid]))
    out, rep = tmp_path / "a.fold", tmp_path / "a.json"
    assert main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(out), "--drive", str(drive),
                 "--steps", "crease0,crease1", "--frames", "3", "--report", str(rep), "-q"]) == 0
    report = json.loads(rep.read_text())
    assert [st["step"] for st in report["states"]] == [-1, 0, 0, 1, 1]
    assert sorted(map(sorted, report["driven_edges"])) == sorted(sorted(s.panel.edges[e].tolist()) for e in mid)
    assert load_fold(out).n_frames == 5


def test_readme_example_runs(tmp_path, monkeypatch):
    """The commands in docs/refold.md, as written."""
    import shlex
    from pathlib import Path

    text = (Path(__file__).resolve().parent.parent / "docs" / "refold.md").read_text()
    block = text.split("```")[1]
    monkeypatch.chdir(tmp_path)
    cmds = [shlex.split(line) for line in block.strip().splitlines() if line.startswith("fabkit ")]
    assert len(cmds) == 3
    for argv in cmds:
        assert main(argv[1:] + ["-q"]) == 0, argv
    assert (tmp_path / "seq.fold").exists() and (tmp_path / "angles.png").exists()
    assert json.loads((tmp_path / "refold.json").read_text())["ok"]


def test_cli_steps_from_a_json_schedule(pair_files, tmp_path):
    d, flat, target = pair_files
    from fabkit.refold import RefoldSolver
    from fabkit.refold.sequence import middle_row_hinges

    s = RefoldSolver(flat, target)
    mid = middle_row_hinges(s.panel)
    sched = tmp_path / "schedule.json"
    sched.write_text(json.dumps([[s.panel.edges[mid[1]].tolist()], [s.panel.edges[mid[0]].tolist()]]))
    out, rep = tmp_path / "a.fold", tmp_path / "a.json"
    assert main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(out), "--steps", str(sched),
                 "--frames", "2", "--report", str(rep), "-q"]) == 0
    states = json.loads(rep.read_text())["states"]
    assert [st["step"] for st in states] == [-1, 0, 1]
    assert main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(out), "--steps", str(sched),
                 "--drive", "all", "-q"]) == 2


def test_flaps_that_cross_are_reported_and_exit_1(tmp_path, capsys):
    from refold_panels import DEG, letter_fold_pair

    flat, target = letter_fold_pair(170 * DEG)
    seq = refold(flat, target, frames=9)
    assert seq.converged.all() and seq.target_distance <= 1e-9 * seq.panel_size
    assert seq.intersections[0] == 0 and seq.intersections[-1] > 0
    # the flap tips meet over the middle at 120 deg: folded to 100 deg the panel stays clear all the way
    assert refold(*letter_fold_pair(100 * DEG), frames=5).intersections.max() == 0
    save_obj(flat, tmp_path / "f.obj")
    save_obj(target, tmp_path / "t.obj")
    out, rep = tmp_path / "s.fold", tmp_path / "r.json"
    assert main(["refold", str(tmp_path / "f.obj"), str(tmp_path / "t.obj"), "-o", str(out), "--frames", "9",
                 "--report", str(rep), "-q"]) == 1
    assert "pass through each other" in capsys.readouterr().err
    assert out.exists() and not json.loads(rep.read_text())["ok"]
    assert main(["refold", str(tmp_path / "f.obj"), str(tmp_path / "t.obj"), "-o", str(out), "--frames", "9",
                 "--no-intersections", "-q"]) == 0
