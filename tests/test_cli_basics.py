"""The `fabkit` command line basics and `fabkit info` on good files."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.fold import FoldFrame, FoldModel
from fabkit.io import save_fold, save_obj
from fabkit.mesh import PolyMesh
from io_meshes import folded_coords, mixed_mesh

ROOT = Path(__file__).parent.parent
DATA = Path(__file__).parent / "data"


def cube_mesh() -> PolyMesh:
    V = [[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)]
    F = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return PolyMesh(V, F, face_data={"side": np.arange(6)})


def test_help_and_version_in_a_subprocess():
    r = subprocess.run([sys.executable, "-m", "fabkit", "--help"], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert r.returncode == 0 and "info" in r.stdout
    r = subprocess.run([sys.executable, "-m", "fabkit", "info", "--help"], capture_output=True, text=True,
                       timeout=60, cwd=ROOT)
    assert r.returncode == 0 and "--report" in r.stdout and "fabkit info" in r.stdout
    r = subprocess.run([sys.executable, "-m", "fabkit", "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("fabkit ")


def test_usage_errors_exit_2_with_one_line(capsys):
    with pytest.raises(SystemExit) as e:
        main(["info"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "required" in err[0]
    with pytest.raises(SystemExit) as e:
        main(["no-such-command"])
    assert e.value.code == 2


def test_info_on_a_cube_obj(tmp_path, capsys):
    save_obj(cube_mesh(), tmp_path / "cube.obj")
    assert main(["info", str(tmp_path / "cube.obj"), "--report", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr().out
    assert "8 vertices, 6 faces (6 quads), 12 edges, 0 boundary loop(s)" in out
    assert "max 1.57 rad" in out
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["format"] == "fabkit.info/1" and r["kind"] == "obj"
    assert r["faces_by_size"] == {"quads": 6}
    assert r["max_abs_angle_defect_rad"] == pytest.approx(np.pi / 2, abs=1e-13)
    assert r["mean_abs_angle_defect_rad"] == pytest.approx(np.pi / 2, abs=1e-13)
    assert r["face_tags"] == ["side"] and r["unit"] == "m"


def test_info_on_a_fold_animation(tmp_path, capsys):
    mesh = mixed_mesh()
    frames = [FoldFrame(folded_coords(mesh, a)) for a in (0.2, 0.4)]
    save_fold(FoldModel.from_mesh(mesh, frames=frames), tmp_path / "p.fold")
    assert main(["info", str(tmp_path / "p.fold"), "--report", str(tmp_path / "r.json"), "--quiet"]) == 0
    assert capsys.readouterr().out == ""  # --quiet
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["kind"] == "fold" and r["frames"] == 2 and r["unit"] == "mm"
    assert r["faces_by_size"] == {"triangles": 2, "quads": 2, "pentagons": 1}
    assert r["face_tags"] == ["column", "middle", "strip"] and r["vertex_tags"] == ["pinned", "weight"]
    assert r["edges_assignment"] == {"B": 9, "F": 3, "U": 2}
    assert r["max_abs_angle_defect_rad"] < 1e-15 and r["max_planarity"] == 0.0
    assert r["boundary_loops"] == 1 and r["interior_vertices"] == 1
    # the fold states are rigid rotations about the hinge: no edge stretches, faces stay planar
    assert r["frames_max_edge_strain"] < 1e-14 and r["frames_max_planarity"] < 1e-14
    assert r["last_frame_max_fold_deg"] == pytest.approx(np.degrees(0.4), abs=1e-9)


def test_info_reports_stretch_in_a_fold_state(tmp_path):
    mesh = mixed_mesh()
    V = folded_coords(mesh, 0.3)
    V[9] *= 1.01  # stretch the pentagon's tip
    save_fold(FoldModel.from_mesh(mesh, frames=[FoldFrame(V)]), tmp_path / "s.fold")
    assert main(["info", str(tmp_path / "s.fold"), "--report", str(tmp_path / "r.json"), "-q"]) == 0
    r = json.loads((tmp_path / "r.json").read_text())
    L0, L1 = mesh.edge_lengths, mesh.with_vertices(V).edge_lengths
    assert r["frames_max_edge_strain"] == pytest.approx(np.max(np.abs(L1 / L0 - 1)), rel=1e-12)
    assert r["frames_max_edge_strain"] > 1e-3


def test_info_on_the_pleat_fixture_reports_the_rotation(capsys):
    assert main(["info", str(DATA / "fold" / "pleat-xz.fold")]) == 0
    out = capsys.readouterr().out
    assert "4 faces (4 quads)" in out and "rotated into z = 0" in out and "file unit 'unit'" in out


def test_info_missing_file_and_report_directory(tmp_path, capsys):
    assert main(["info", str(tmp_path / "nope.obj")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"fabkit info: error: {tmp_path / 'nope.obj'}: no such file"]
    save_obj(cube_mesh(), tmp_path / "c.obj")
    assert main(["info", str(tmp_path / "c.obj"), "--report", str(tmp_path / "no" / "r.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "output directory does not exist" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.obj"]


def test_file_formats_readme_examples_run(tmp_path):
    """The console examples in docs/file-formats.md produce the output shown there."""
    import re
    import shlex

    doc = (ROOT / "docs" / "file-formats.md").read_text()
    (tmp_path / "tests").symlink_to(ROOT / "tests")
    blocks = re.findall(r"```console\n(.*?)```", doc, flags=re.S)
    assert blocks
    checked = 0
    for block in blocks:
        for cmd, shown in re.findall(r"^\$ (.*)\n((?:(?!\$ ).*\n)*)", block, flags=re.M):
            argv = shlex.split(cmd)
            assert argv[0] == "fabkit"
            r = subprocess.run([sys.executable, "-m", "fabkit", *argv[1:]], capture_output=True, text=True,
                               timeout=120, cwd=tmp_path)
            out = (r.stdout + r.stderr).splitlines()
            for line in shown.splitlines():
                if line.strip() == "..." or re.search(r"\de-1\d", line):  # floating-point noise is not pinned
                    continue
                assert line in out, (cmd, line, out)
                checked += 1
    assert checked >= 8


def test_info_frame_option_measures_a_fold_state(tmp_path, capsys):
    mesh = mixed_mesh()
    save_fold(FoldModel.from_mesh(mesh, frames=[FoldFrame(folded_coords(mesh, a)) for a in (0.2, 0.4)]),
              tmp_path / "p.fold")
    assert main(["info", str(tmp_path / "p.fold"), "--frame", "-1", "--report", str(tmp_path / "r.json")]) == 0
    assert "(measured in frame 2 of 2, a fold state)" in capsys.readouterr().out
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["measured_frame"] == 2
    # folding is an isometry: the interior vertex keeps zero defect, the faces stay planar
    assert r["max_abs_angle_defect_rad"] < 1e-14 and r["max_planarity"] < 1e-14
    assert main(["info", str(tmp_path / "p.fold"), "--frame", "3"]) == 2
    assert "fold states 1..2" in capsys.readouterr().err
    save_obj(mesh, tmp_path / "m.obj")
    assert main(["info", str(tmp_path / "m.obj"), "--frame", "1"]) == 2
    assert "--frame: only FOLD files have frames" in capsys.readouterr().err


def test_info_compares_stored_and_measured_fold_angles(tmp_path):
    mesh = mixed_mesh()
    hinge = np.zeros(mesh.n_edges, bool)
    hinge[[3, 9]] = True  # edges (1, 4) and (4, 7) on the line x = 0.1
    assignment = np.where(hinge, "V", FoldModel.from_mesh(mesh).edges_assignment)

    def run(frames, name):
        model = FoldModel.from_mesh(mesh, assignment, np.where(hinge, 0.4, 0.0), frames=frames)
        save_fold(model, tmp_path / name)
        assert main(["info", str(tmp_path / name), "--report", str(tmp_path / "r.json"), "-q"]) == 0
        return json.loads((tmp_path / "r.json").read_text())

    good = run([FoldFrame(folded_coords(mesh, a), np.where(hinge, a, 0.0)) for a in (0.2, 0.4)], "good.fold")
    assert good["frames_max_fold_angle_mismatch_deg"] < 1e-12 and good["frames_creases_bent_wrong_way"] == 0
    # coordinates folded to 0.2 rad while the frame claims 0.4 rad
    off = run([FoldFrame(folded_coords(mesh, 0.2), np.where(hinge, 0.4, 0.0))], "off.fold")
    assert off["frames_max_fold_angle_mismatch_deg"] == pytest.approx(np.degrees(0.2), abs=1e-9)
    # the valley crease bent as a mountain in a frame whose own angles are unknown
    wrong = run([FoldFrame(folded_coords(mesh, -0.3), np.where(hinge, np.nan, 0.0))], "wrong.fold")
    assert wrong["frames_creases_bent_wrong_way"] == 2
