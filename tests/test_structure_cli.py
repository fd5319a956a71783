"""`fabkit info` shows the panel structure, `fabkit tag` writes it as tags, and `fabkit refold` on an
untagged panel: the default drive, --drive all, and a non-converging schedule (exit 1, states kept)."""
import json

import numpy as np

from fabkit.cli import main
from fabkit.io.fold import load_fold
from fabkit.io.obj import load_obj, save_obj
from structure_panels import noisy, plain, reflect_tagged, shuffled, true_creases


def test_info_prints_the_inferred_structure(tmp_path, capsys):
    tagged = reflect_tagged(2, 90.0)
    p = tmp_path / "p.obj"
    save_obj(plain(tagged), p)
    r = tmp_path / "info.json"
    assert main(["info", str(p), "--report", str(r)]) == 0
    out = capsys.readouterr().out
    assert "structure (creases inferred" in out and "crease 0 (strips 0|1): 12 edges" in out
    assert "clamp face" in out and "grip candidates" in out
    st = json.loads(r.read_text())["structure"]
    assert st["strips"] == 3 and st["crease_edges"] == int(true_creases(tagged).sum())
    assert {c["M"] + c["V"] for c in st["creases"]} == {12}
    from fabkit.structure import panel_structure

    def rows(creases):
        return sorted((c["edges"], c["M"], c["V"], round(c["min_fold_deg"], 9), round(c["max_fold_deg"], 9))
                      for c in creases)

    assert rows(st["creases"]) == rows(panel_structure(tagged).summary(tagged)["creases"])


def test_tag_writes_editable_tags_that_win(tmp_path, capsys):
    tagged = reflect_tagged(1, 60.0)
    mesh, new_of_old, _ = shuffled(noisy(plain(tagged), 0.005), seed=4)
    p, out = tmp_path / "p.obj", tmp_path / "t.obj"
    save_obj(mesh, p)
    assert main(["tag", str(p), "-o", str(out), "-q"]) == 0
    text = out.read_text()
    assert "# fabkit face_data strip" in text and "# fabkit face_data middle" in text
    back = load_obj(out)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    assert back.faces_list() == mesh.faces_list()
    truth = {tuple(sorted(new_of_old[e].tolist())) for e in tagged.edges[true_creases(tagged)]}
    assert {tuple(e) for e in back.edges[true_creases(back)].tolist()} == truth
    assert int(back.face_data["middle"].sum()) == 2
    # the user edits a tag: it wins over the geometry
    assert main(["info", str(out), "-q"]) == 0
    edited = back.with_data(face_data={"strip": np.zeros(back.n_faces, np.int64)})
    save_obj(edited, tmp_path / "e.obj")
    r = tmp_path / "r.json"
    assert main(["info", str(tmp_path / "e.obj"), "-q", "--report", str(r)]) == 0
    st = json.loads(r.read_text())["structure"]
    assert st["source"]["creases"] == "tags" and st["crease_edges"] == 0
    assert main(["tag", str(p), "-o", str(p)]) == 2
    assert main(["tag", str(tmp_path / "e.obj"), "-o", str(tmp_path / "f.obj"), "--infer", "-q"]) == 0
    assert int(true_creases(load_obj(tmp_path / "f.obj")).sum()) == len(truth)


def test_reflect_preset_without_tags_refolds_by_default_and_with_drive_all(tmp_path, capsys):
    """generate reflect, delete the tag lines, unfold, refold: default and --drive all."""
    r, p, f = tmp_path / "r.obj", tmp_path / "p.obj", tmp_path / "f.obj"
    assert main(["generate", "reflect", "-o", str(r), "-q"]) == 0
    p.write_text("".join(line for line in r.read_text().splitlines(True) if not line.startswith("# fabkit")))
    assert main(["unfold", str(p), "-o", str(f), "-q"]) == 0
    for extra in ([], ["--drive", "all"]):
        seq, rep = tmp_path / "s.fold", tmp_path / "s.json"
        assert main(["refold", str(f), str(p), "-o", str(seq), "--frames", "6", "--report", str(rep), "-q"]
                    + extra) == 0
        report = json.loads(rep.read_text())
        assert report["ok"] and report["summary"]["target_distance_rel"] <= 1e-6
        model = load_fold(seq)
        assert model.n_frames == 6 and "middle" in model.faces_data
        assert all(np.all(np.isfinite(fr.edges_fold_angle)) for fr in model.frames)
    assert len(report["driven_edges"]) == 24                 # --drive all: the 24 crease edges, not every edge


def test_refold_that_does_not_converge_exits_1_with_the_states_it_reached(tmp_path, capsys):
    from fabkit.refold import RefoldSolver

    tagged = reflect_tagged(1, 60.0, columns=6, rows=2)
    flat = tagged.with_vertices(np.column_stack([tagged.vertex_data["uv"], np.zeros(tagged.n_vertices)]))
    target = plain(tagged)
    flat = plain(flat)
    fp, tp = tmp_path / "flat.obj", tmp_path / "target.obj"
    save_obj(flat, fp)
    save_obj(target, tp)
    s = RefoldSolver(flat, target)
    every = [s.panel.edges[e].tolist() for e in np.flatnonzero((s.panel.edge_kind == 1) | (s.panel.edge_kind == 2))]
    drive = tmp_path / "drive.json"
    drive.write_text(json.dumps(every))
    seq, rep = tmp_path / "s.fold", tmp_path / "s.json"
    rc = main(["refold", str(fp), str(tp), "-o", str(seq), "--drive", str(drive), "--frames", "4",
               "--report", str(rep), "-q"])
    err = capsys.readouterr().err
    assert rc == 1 and "did not converge" in err and "worst hinge" in err
    report = json.loads(rep.read_text())
    assert not report["ok"] and report["summary"]["failed_state"] >= 1
    model = load_fold(seq)
    assert model.n_frames == report["summary"]["failed_state"] and "fabkit:failure" in model.file_data
    assert all(st["converged"] for st in report["states"])
