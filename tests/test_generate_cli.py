"""`fabkit generate`: acceptance numbers measured on the written files, and one-line refusals."""
import json

import numpy as np
import pytest

from fabkit import measures
from fabkit.cli import main
from fabkit.io.obj import load_obj


def test_reflect_written_file_is_exactly_developable(tmp_path, capsys):
    out = tmp_path / "r.obj"
    assert main(["generate", "reflect", "-o", str(out), "--report", str(tmp_path / "r.json")]) == 0
    m = load_obj(out)
    assert np.abs(measures.interior_angle_defect(m)).max() <= 1e-12
    assert measures.face_planarity(m).max() <= 1e-12
    assert {"strip", "column", "middle"} <= set(m.face_data) and "uv" in m.vertex_data
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["vertices"] == m.n_vertices and report["max_abs_angle_defect_rad"] <= 1e-12
    assert report["creases"][0]["min_fold_deg"] > 59.0
    text = capsys.readouterr().out
    assert "max |angle defect|" in text and "r.obj" in text


def test_reflect_two_creases_fine(tmp_path):
    out = tmp_path / "r2.obj"
    args = ["generate", "reflect", "-o", str(out), "--creases", "2", "--fold", "45", "--columns", "99",
            "--rows", "33", "--radius", "0.8", "--width", "0.9", "-q"]
    assert main(args) == 0
    m = load_obj(out)
    assert m.n_vertices == 100 * 100
    assert np.abs(measures.interior_angle_defect(m)).max() <= 1e-12
    assert measures.face_planarity(m).max() <= 1e-12
    assert sorted(np.unique(m.face_data["strip"])) == [0, 1, 2]
    d = measures.dihedral_angles(m)
    st = m.face_data["strip"]
    ef = m.edge_faces
    inner = np.all(ef >= 0, axis=1)
    a, b = st[np.maximum(ef[:, 0], 0)], st[np.maximum(ef[:, 1], 0)]
    assert np.all(d[inner & (np.minimum(a, b) == 0) & (a != b)] > 0)  # valley
    assert np.all(d[inner & (np.minimum(a, b) == 1) & (a != b)] < 0)  # mountain (fold2 defaults to -fold)


@pytest.mark.parametrize("preset, extra, faces", [
    ("cube", ["--subdivide", "2"], 96),
    ("prism", ["--sides", "5"], 7),
    ("grid", ["--nx", "3", "--ny", "4"], 12),
    ("canopy", ["--stations", "5"], 8),
])
def test_basic_presets(tmp_path, preset, extra, faces):
    out = tmp_path / f"{preset}.obj"
    assert main(["generate", preset, "-o", str(out), "-q", *extra]) == 0
    assert load_obj(out).n_faces == faces


@pytest.mark.parametrize("argv, words", [
    (["generate", "blob"], "unknown preset"),
    (["generate", "reflect", "--radius", "-1"], "--radius must be positive"),
    (["generate", "reflect", "--radius", "abc"], "--radius must be a number"),
    (["generate", "reflect", "--radius", "nan"], "--radius must be finite"),
    (["generate", "reflect", "--columns", "2.5"], "--columns must be an integer"),
    (["generate", "reflect", "--creases", "3"], "--creases must be 1 or 2"),
    (["generate", "reflect", "--fold2", "30"], "need --creases 2"),
    (["generate", "reflect", "--offset", "0.9"], "upper edge"),
    (["generate", "reflect", "--fold", "0"], "--fold must be non-zero and between -180 and 180 degrees"),
    (["generate", "reflect", "--arc", "400"], "--arc must be between 0 and 360 degrees"),
    (["generate", "reflect", "--creases", "2", "--skew2", "95"], "--skew2 must be between -90 and 90 degrees"),
    (["generate", "cube", "--radius", "1"], "has no parameter --radius"),
    (["generate", "prism", "--sides", "2"], "sides"),
    (["generate", "canopy", "--stations", "2"], "stations"),
    (["generate", "trifold", "--bevel", "0.7"], "bevel"),
    (["generate", "grid", "--nx", "100000", "--ny", "100000"], "lower the resolution"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, argv, words):
    out = tmp_path / "x.obj"
    assert main([*argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_unknown_option_is_a_usage_error(tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["generate", "reflect", "-o", str(tmp_path / "x.obj"), "--frobnicate", "1"])
    assert exc.value.code == 2


def test_png_picture(tmp_path):
    png = tmp_path / "r.png"
    assert main(["generate", "reflect", "-o", str(tmp_path / "r.obj"), "--creases", "2", "--png", str(png), "-q"]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert main(["generate", "trifold", "-o", str(tmp_path / "t.obj"), "--resolution", "4", "--png",
                 str(tmp_path / "t.png"), "-q"]) == 0
    assert (tmp_path / "t.png").stat().st_size > 10_000
    assert main(["generate", "cube", "-o", str(tmp_path / "c.obj"), "--png", str(tmp_path / "no" / "c.png")]) == 2
    assert not (tmp_path / "c.obj").exists() and not list(tmp_path.glob("**/.*.tmp"))
