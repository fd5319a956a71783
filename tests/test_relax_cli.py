"""`fabkit relax` end to end: exit codes 0/1/2, output file contract, JSON report."""
import json

import numpy as np

import pytest

from fabkit.cli import main
from fabkit.generate import reflect_panel
from fabkit.io.obj import load_obj, save_obj

from relax_meshes import perturbed


@pytest.fixture
def noisy_obj(tmp_path):
    truth = reflect_panel(columns=10, rows=3)
    noisy, _ = perturbed(truth, 0.01, seed=9)
    path = tmp_path / "noisy.obj"
    save_obj(noisy, path)
    return path, noisy


def test_relax_writes_same_topology_and_a_report(tmp_path, noisy_obj, capsys):
    src, noisy = noisy_obj
    out, rep = tmp_path / "out.obj", tmp_path / "r.json"
    assert main(["relax", str(src), "-o", str(out), "--report", str(rep)]) == 0
    assert "converged" in capsys.readouterr().out
    res = load_obj(out)
    assert res.faces_list() == noisy.faces_list() and res.n_vertices == noisy.n_vertices
    assert set(res.face_data) == set(noisy.face_data)
    r = json.loads(rep.read_text())
    assert r["converged"] is True and r["output"] == str(out)
    f = r["final"]
    assert f["max_abs_angle_defect_rad"] <= 1e-8 and f["max_planarity"] <= 1e-8
    assert len(f["vertex_angle_defect_rad"]) == noisy.n_vertices and len(f["face_planarity"]) == noisy.n_faces
    assert f["max_displacement_m"] > 0 and f["mean_displacement_m"] > 0
    h = r["history"]
    assert h and {"max_defect", "mean_defect", "max_planarity", "mean_planarity", "kinetic_energy"} <= set(h[0])
    assert any(x["kinetic_energy"] > 0 for x in h)
    assert r["options"]["tol_defect"] == 1e-8


def test_boundary_row_option_keeps_the_input_topology(tmp_path):
    from fabkit.generate import trifold_panel

    src, out = tmp_path / "tri.obj", tmp_path / "row.obj"
    tri = trifold_panel(resolution=16)
    save_obj(tri, src)
    assert main(["relax", str(src), "-o", str(out), "--boundary", "row-in-plane", "-q"]) == 0
    res = load_obj(out)
    assert res.faces_list() == tri.faces_list() and res.n_vertices == tri.n_vertices


def test_not_converged_exits_1_and_writes_nothing(tmp_path, noisy_obj, capsys):
    src, _ = noisy_obj
    out, rep = tmp_path / "out.obj", tmp_path / "r.json"
    code = main(["relax", str(src), "-o", str(out), "--max-iter", "2", "--newton-max-iter", "1", "--no-fallback",
                 "--report", str(rep)])
    assert code == 1
    err = capsys.readouterr().err
    assert "did not converge" in err and "max |angle defect|" in err and "no output written" in err
    assert not out.exists()
    assert json.loads(rep.read_text())["converged"] is False
    code = main(["relax", str(src), "-o", str(out), "--max-iter", "2", "--newton-max-iter", "1", "--no-fallback",
                 "--write-unconverged", "-q"])
    assert code == 1 and out.exists()


def _write(path, text):
    path.write_text(text)
    return path


@pytest.mark.parametrize("name,text,needle", [
    ("nonmanifold.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 1 1 1\n"
                        "f 1 2 3\nf 2 1 4\nf 1 2 5\n", "non-manifold"),
    ("nan.obj", "v 0 0 0\nv 1 0 nan\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 3\n", "non-finite"),
    ("single.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", "1 face"),
    ("strip.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nf 1 2 5 4\nf 2 3 6 5\n",
     "no interior vertex"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, name, text, needle):
    src = _write(tmp_path / name, text)
    out = tmp_path / "out.obj"
    assert main(["relax", str(src), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err and name in err
    assert not out.exists()


def test_bad_option_exits_2(tmp_path, noisy_obj, capsys):
    src, _ = noisy_obj
    assert main(["relax", str(src), "-o", str(tmp_path / "o.obj"), "--tol-defect", "0"]) == 2
    assert "tol_defect" in capsys.readouterr().err
    assert main(["relax", str(src), "-o", str(tmp_path / "o.obj"), "--fixed", "99999"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_crease_fairness_and_kept_edge_lengths_from_the_command_line(tmp_path, noisy_obj):
    import numpy as np

    src, noisy = noisy_obj
    out, rep = tmp_path / "out.obj", tmp_path / "r.json"
    lengths = tmp_path / "lengths.json"
    u, v = (int(i) for i in noisy.edges[5])
    lengths.write_text(json.dumps({"edges": [[v, u]], "lengths": [0.05]}))
    args = ["relax", str(src), "-o", str(out), "--report", str(rep), "--crease-fairness", "10",
            "--keep-boundary-lengths", "--edge-lengths", str(lengths), "-q"]
    assert main(args) == 0
    r = json.loads(rep.read_text())
    assert any(h["phase"] == "fair" for h in r["history"]) and "crease fairing" in r["message"]
    assert r["options"]["crease_fairness"] == 10.0
    res = load_obj(out)
    b = noisy.topology.boundary_edge_mask
    assert np.abs(res.edge_lengths[b] / noisy.edge_lengths[b] - 1).max() <= 1e-8
    assert abs(res.edge_lengths[5] - 0.05) <= 1e-8 * 0.05


@pytest.mark.parametrize("content, message", [
    ('{"edges": [[0, 999]], "lengths": [0.1]}', "is not an edge"),
    ('{"edges": [[0, 1]], "lengths": [-1]}', "positive number"),
    ('{"edges": [[0, 1]]}', "expected an object"),
    ('{"edges": [[0, 1, 2]], "lengths": [1]}', "pairs"),
    ("not json", "not a JSON edge-length file"),
])
def test_bad_edge_length_files_exit_2_with_one_line(tmp_path, noisy_obj, capsys, content, message):
    src, _ = noisy_obj
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    out = tmp_path / "out.obj"
    assert main(["relax", str(src), "-o", str(out), "--edge-lengths", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and str(bad) in err[0]
    assert not out.exists()
    assert main(["relax", str(src), "-o", str(out), "--crease-fairness", "-1"]) == 2


def _saddle(path, n=6, height=1.5):
    """A plain OBJ saddle z = h (x^2 - y^2): far from developable, relax must move it a lot."""
    xs, ys = np.meshgrid(np.linspace(-0.4, 0.4, n + 1), np.linspace(-0.4, 0.4, n + 1))
    V = np.column_stack([xs.ravel(), ys.ravel(), height * (xs.ravel() ** 2 - ys.ravel() ** 2)])
    F = [[j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i]
         for j in range(n) for i in range(n)]
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in V.tolist()] + ["f " + " ".join(str(i + 1) for i in f) for f in F]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_relax_that_moves_the_panel_too_far_exits_1(tmp_path, capsys):
    src = _saddle(tmp_path / "saddle.obj")
    out, rep = tmp_path / "r.obj", tmp_path / "r.json"
    assert main(["relax", str(src), "-o", str(out), "--report", str(rep)]) == 1
    err = capsys.readouterr().err
    assert "more than --max-move 0.05" in err and "another shape" in err
    assert not out.exists()
    r = json.loads(rep.read_text())
    assert r["max_move"]["ok"] is False and r["max_move"]["moved_m"] > r["max_move"]["limit_m"]
    # a generous limit lets the same relax through
    assert main(["relax", str(src), "-o", str(out), "--max-move", "1"]) == 0 and out.exists()


def test_relax_reads_millimetres_with_units_and_reports_the_unit(tmp_path, capsys):
    from fabkit.generate.reflect import reflect_panel

    panel = reflect_panel(columns=8, rows=2)
    V = panel.vertices * 1000
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in V.tolist()] + [
        "f " + " ".join(str(i + 1) for i in f) for f in panel.faces_list()]
    (tmp_path / "mm.obj").write_text("\n".join(lines) + "\n")
    assert main(["relax", str(tmp_path / "mm.obj"), "-o", str(tmp_path / "a.obj")]) == 0
    assert "pass --units mm" in capsys.readouterr().err
    assert main(["relax", str(tmp_path / "mm.obj"), "-o", str(tmp_path / "b.obj"), "--units", "mm",
                 "--report", str(tmp_path / "b.json")]) == 0
    assert "note" not in capsys.readouterr().err
    r = json.loads((tmp_path / "b.json").read_text())
    assert r["loaded"]["unit"] == "mm" and r["unit"] == "m"
    from fabkit.io.load import load_panel

    b, info = load_panel(tmp_path / "b.obj")
    assert info.unit_source == "from the file"
    np.testing.assert_allclose(b.vertices, panel.vertices, atol=1e-12)
