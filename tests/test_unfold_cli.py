"""`fabkit unfold`: outputs, exit codes, and nothing half-written on bad input."""
import json

import ezdxf
import numpy as np
import pytest

from fabkit.cli import main
from fabkit.io.obj import load_obj, save_obj
from unfold_shapes import folded_grid, sphere_cap


@pytest.fixture
def panel(tmp_path):
    from fabkit.generate import reflect_panel

    path = tmp_path / "panel.obj"
    save_obj(reflect_panel(columns=16, rows=3), path)
    return path


def test_unfold_writes_everything(tmp_path, panel, capsys):
    out = {k: tmp_path / f"flat.{k}" for k in ("obj", "dxf", "svg", "png")}
    rc = main(["unfold", str(panel), "-o", str(out["obj"]), "--dxf", str(out["dxf"]), "--svg", str(out["svg"]),
               "--png", str(out["png"]), "--max-error", "1e-9", "--panel-id", "A1", "--report", str(tmp_path / "r.json")])
    assert rc == 0
    assert "max" in capsys.readouterr().out
    src, flat = load_obj(panel), load_obj(out["obj"])
    assert flat.faces_list() == src.faces_list() and flat.n_vertices == src.n_vertices
    assert np.all(flat.vertices[:, 2] == 0)
    assert np.array_equal(flat.face_data["strip"], src.face_data["strip"])
    assert np.array_equal(flat.vertex_data["uv"], src.vertex_data["uv"])
    rel = np.abs(flat.edge_lengths / src.edge_lengths - 1)
    assert rel.max() < 1e-9
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["ok"] and report["problems"] == [] and report["format"] == "fabkit.unfold/1"
    assert report["development"]["max_relative_deviation"] <= 1e-9
    assert report["creases"]["V"] > 0 and report["creases"]["source"].startswith("face_data")
    doc = ezdxf.readfile(out["dxf"])
    assert [t.dxf.text for t in doc.modelspace().query("TEXT")] == ["A1", "FACE UP: FRONT (valleys fold up)"]
    assert out["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out["svg"].read_text().startswith("<?xml")


@pytest.mark.parametrize("method", ["conformal", "authalic"])
def test_other_methods(tmp_path, panel, method):
    rc = main(["unfold", str(panel), "-o", str(tmp_path / "f.obj"), "--method", method, "-q",
               "--report", str(tmp_path / "r.json")])
    assert rc == 0
    assert json.loads((tmp_path / "r.json").read_text())["development"]["method"] == method


def test_max_error_exceeded_exits_1_and_says_why(tmp_path, capsys):
    cap = tmp_path / "cap.obj"
    save_obj(sphere_cap(), cap)
    rc = main(["unfold", str(cap), "-o", str(tmp_path / "f.obj"), "--max-error", "1e-4", "--report",
               str(tmp_path / "r.json"), "-q"])
    assert rc == 1
    assert "exceeds --max-error" in capsys.readouterr().err
    report = json.loads((tmp_path / "r.json").read_text())
    assert not report["ok"] and report["development"]["flipped_faces"] == 0
    assert report["development"]["max_relative_deviation"] > 1e-4
    assert (tmp_path / "f.obj").exists()
    assert main(["unfold", str(cap), "-o", str(tmp_path / "g.obj"), "--max-error", "0.5", "-q"]) == 0


def test_untagged_panel_uses_the_crease_angle(tmp_path):
    mesh, _ = folded_grid(np.radians(-30))
    plain = type(mesh)(mesh.vertices, mesh.faces_list())
    path = tmp_path / "fold.obj"
    save_obj(plain, path)
    r = tmp_path / "r.json"
    assert main(["unfold", str(path), "-o", str(tmp_path / "f.obj"), "--dxf", str(tmp_path / "f.dxf"), "-q",
                 "--report", str(r)]) == 0
    assert json.loads(r.read_text())["creases"]["M"] == 4
    assert main(["unfold", str(path), "-o", str(tmp_path / "f.obj"), "--crease-angle", "45", "-q", "--report", str(r)]) == 0
    assert json.loads(r.read_text())["creases"]["M"] == 0


def _assert_nothing_written(tmp_path, keep):
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(keep)


@pytest.mark.parametrize("text,needle", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "vertex"),
    ("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", "non-finite"),
    ("hello\n", "line 1"),
])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, text, needle):
    bad = tmp_path / "bad.obj"
    bad.write_text(text)
    rc = main(["unfold", str(bad), "-o", str(tmp_path / "f.obj"), "--dxf", str(tmp_path / "f.dxf"),
               "--svg", str(tmp_path / "f.svg"), "--png", str(tmp_path / "f.png"), "--report", str(tmp_path / "r.json")])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.obj" in err and needle in err
    _assert_nothing_written(tmp_path, ["bad.obj"])


def test_closed_mesh_is_refused_naming_the_file(tmp_path, capsys):
    cube = tmp_path / "cube.obj"
    cube.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                    "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")
    rc = main(["unfold", str(cube), "-o", str(tmp_path / "f.obj"), "--dxf", str(tmp_path / "f.dxf")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "cube.obj" in err and "closed" in err
    _assert_nothing_written(tmp_path, ["cube.obj"])


def test_bad_arguments_exit_2(tmp_path, panel, capsys):
    base = ["unfold", str(panel), "-o", str(tmp_path / "f.obj")]
    assert main(base + ["--max-error", "-1"]) == 2
    assert main(base + ["--max-error", "nan"]) == 2
    assert main(base + ["--crease-angle", "0"]) == 2
    assert main(base + ["--norm", "1"]) == 2
    assert main(base + ["--norm", "3", "--method", "conformal"]) == 2
    assert main(base + ["--dxf", str(tmp_path / "f.obj")]) == 2
    assert main(base + ["--svg", str(tmp_path / "missing" / "f.svg")]) == 2
    assert main(["unfold", str(panel), "-o", str(panel)]) == 2
    assert main(base + ["--dxf", str(tmp_path)]) == 2
    with pytest.raises(SystemExit) as exc:
        main(base + ["--method", "magic"])
    assert exc.value.code == 2
    _assert_nothing_written(tmp_path, ["panel.obj"])


def test_a_failing_writer_leaves_no_output_behind(tmp_path, panel, monkeypatch, capsys):
    from fabkit.unfold import plot as unfold_plot

    def broken(*args, **kwargs):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(unfold_plot, "plot_unfold_error", broken)
    rc = main(["unfold", str(panel), "-o", str(tmp_path / "f.obj"), "--dxf", str(tmp_path / "f.dxf"),
               "--svg", str(tmp_path / "f.svg"), "--png", str(tmp_path / "f.png"), "--report", str(tmp_path / "r.json")])
    assert rc == 3 and "disk on fire" in capsys.readouterr().err
    _assert_nothing_written(tmp_path, ["panel.obj"])


def test_default_max_error_fails_a_non_developable_mesh(tmp_path, capsys):
    cap = tmp_path / "cap.obj"
    save_obj(sphere_cap(), cap)
    assert main(["unfold", str(cap), "-o", str(tmp_path / "f.obj"), "-q", "--report", str(tmp_path / "r.json")]) == 1
    assert "exceeds --max-error 0.001" in capsys.readouterr().err
    assert json.loads((tmp_path / "r.json").read_text())["max_error"] == 1e-3


def test_dxf_extents_and_units(panel, tmp_path):
    dxf = tmp_path / "f.dxf"
    assert main(["unfold", str(panel), "-o", str(tmp_path / "f.obj"), "--dxf", str(dxf), "-q"]) == 0
    doc = ezdxf.readfile(dxf)
    assert doc.header["$INSUNITS"] == 4
    lo, hi = np.array(doc.header["$EXTMIN"])[:2], np.array(doc.header["$EXTMAX"])[:2]
    pts = np.array([p[:2] for e in doc.modelspace().query("LWPOLYLINE[layer=='CUT']") for p in e.get_points()])
    np.testing.assert_allclose(lo, pts.min(axis=0), atol=1e-9)
    np.testing.assert_allclose(hi, pts.max(axis=0), atol=1e-9)


def test_flat_fold_output_holds_the_flat_and_the_folded_state(panel, tmp_path):
    from fabkit.io.fold import load_fold

    assert main(["unfold", str(panel), "-o", str(tmp_path / "flat.fold"), "-q"]) == 0
    model = load_fold(tmp_path / "flat.fold")
    assert model.n_frames == 1 and np.all(model.vertices_coords[:, 2] == 0)
    np.testing.assert_allclose(model.frames[0].vertices_coords, load_obj(panel).vertices, atol=1e-12)
    assert set(model.edges_assignment) >= {"B", "V", "F"}
