"""Acceptance: one plain reflect panel as users bring it (metres, millimetres, shuffled and
triangulated, FOLD of another tool, Rhino .3dm) gives the same results through relax -> unfold ->
refold, with the unit declared by the file or given once with --units (the note says so otherwise)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial import cKDTree

from fabkit.cli import main
from fabkit.io.fold import load_fold
from fabkit.io.load import load_panel
from panel_inputs import fold_other_tool, plain_obj, reflect, rhino_3dm, shuffled, triangulated

COLUMNS, ROWS = 24, 4  # the reflect preset's own resolution


@pytest.fixture(scope="module")
def base():
    return reflect(COLUMNS, ROWS)


def _variants(d, V, F):
    S, G, _ = shuffled(V * 1000, F)
    return {
        "metres.obj": (plain_obj(d / "metres.obj", V, F), []),
        "millimetres.obj": (plain_obj(d / "millimetres.obj", V * 1000, F), ["--units", "mm"]),
        "shuffled-triangulated-mm.obj": (plain_obj(d / "shuf.obj", S, triangulated(G)), ["--units", "mm"]),
        "other-tool.fold": (fold_other_tool(d / "other.fold", S, triangulated(G, seed=9), {}, lower=True),
                            ["--units", "mm"]),
        "rhino.3dm": (rhino_3dm(d / "rhino.3dm", S, triangulated(G, seed=11)), []),
    }


def _match(a: np.ndarray, b: np.ndarray, atol: float) -> np.ndarray:
    """Index j with a[i] == b[j[i]] (within atol), a bijection."""
    dist, j = cKDTree(b).query(a)
    assert dist.max() <= atol, dist.max()
    assert len(set(j.tolist())) == len(a)
    return j


@pytest.fixture(scope="module")
def runs(tmp_path_factory, base):
    d = tmp_path_factory.mktemp("anypanel")
    V, F = base
    out = {}
    for name, (path, flags) in _variants(d, V, F).items():
        stem = d / name.replace(".", "_")
        assert main(["relax", str(path), "-o", f"{stem}_r.obj", "-q", "--report", f"{stem}_relax.json", *flags]) == 0
        assert main(["unfold", f"{stem}_r.obj", "-o", f"{stem}_flat.fold", "-q", "--report",
                     f"{stem}_unfold.json"]) == 0
        out[name] = {"relax": json.loads(open(f"{stem}_relax.json").read()),
                     "unfold": json.loads(open(f"{stem}_unfold.json").read()),
                     "relaxed": load_panel(f"{stem}_r.obj")[0], "flat": load_fold(f"{stem}_flat.fold"),
                     "stem": stem}
    return out


def test_unit_is_declared_or_given_once(tmp_path, base, capsys):
    V, F = base
    plain_obj(tmp_path / "mm.obj", V * 1000, F)
    assert main(["relax", str(tmp_path / "mm.obj"), "-o", str(tmp_path / "r.obj"), "-q"]) == 0
    assert "pass --units mm" in capsys.readouterr().err  # 758.7 m across read as metres: the note says so
    # after --units once, every later stage reads the unit from the file
    assert main(["relax", str(tmp_path / "mm.obj"), "-o", str(tmp_path / "r.obj"), "-q", "--units", "mm"]) == 0
    assert main(["unfold", str(tmp_path / "r.obj"), "-o", str(tmp_path / "f.fold"), "-q"]) == 0
    assert capsys.readouterr().err == ""


def test_every_variant_relaxes_and_unfolds_to_the_same_panel(runs, base):
    V, F = base
    size = float(np.linalg.norm(np.ptp(V, axis=0)))
    ref = runs["metres.obj"]
    for name, r in runs.items():
        mesh = r["relaxed"]
        assert mesh.n_faces == len(F), name  # triangulated quads merged back
        j = _match(mesh.vertices, V, atol=1e-12 * size)  # same vertices (exact input: relax keeps it)
        final = r["relax"]["final"]
        assert final["max_abs_angle_defect_rad"] <= 1e-8 and final["max_planarity"] <= 1e-8, name
        assert r["relax"]["loaded"]["unit"] in ("mm", "m"), name
        dev = r["unfold"]["development"]
        assert dev["max_relative_deviation"] <= 1e-9, name
        assert r["unfold"]["creases"] == ref["unfold"]["creases"], name
        # the flat patterns are congruent: every edge has the reference's length, vertex by vertex
        flat, flat_ref = r["flat"], ref["flat"]
        ref_of = {tuple(sorted(e)): k for k, e in enumerate(flat_ref.edges_vertices.tolist())}
        L = np.linalg.norm(np.diff(flat.vertices_coords[flat.edges_vertices], axis=1)[:, 0], axis=1)
        L_ref = np.linalg.norm(np.diff(flat_ref.vertices_coords[flat_ref.edges_vertices], axis=1)[:, 0], axis=1)
        k = [ref_of[tuple(sorted((int(j[a]), int(j[b]))))] for a, b in flat.edges_vertices.tolist()]
        np.testing.assert_allclose(L, L_ref[k], rtol=0, atol=1e-12 * size, err_msg=name)
        letters = dict(zip(map(tuple, flat_ref.edges_vertices.tolist()), flat_ref.edges_assignment.tolist()))
        mine = [letters[tuple(sorted((int(j[a]), int(j[b]))))] for a, b in flat.edges_vertices.tolist()]
        assert flat.edges_assignment.tolist() == mine, name


@pytest.mark.slow
@pytest.mark.parametrize("name", ["metres.obj", "rhino.3dm"])
def test_refold_of_the_flat_fold_reaches_the_panel(runs, base, name):
    V, F = base
    size = float(np.linalg.norm(np.ptp(V, axis=0)))
    r = runs[name]
    stem = r["stem"]
    assert main(["refold", f"{stem}_flat.fold", "-o", f"{stem}_seq.fold", "--drive", "all", "--frames", "3", "-q",
                 "--report", f"{stem}_refold.json"]) == 0
    seq = load_fold(f"{stem}_seq.fold")
    last = seq.frames[-1].vertices_coords
    target = r["relaxed"].vertices
    rep = json.loads(open(f"{stem}_refold.json").read())
    assert rep["ok"]
    # the last state is the panel up to a rigid motion: compare edge lengths and the target distance
    L = np.linalg.norm(last[seq.edges_vertices[:, 0]] - last[seq.edges_vertices[:, 1]], axis=1)
    L0 = np.linalg.norm(target[seq.edges_vertices[:, 0]] - target[seq.edges_vertices[:, 1]], axis=1)
    np.testing.assert_allclose(L, L0, rtol=0, atol=1e-9 * size)


@pytest.mark.slow
def test_refold_from_another_tools_crease_pattern_with_a_folded_frame(tmp_path, base):
    """A FOLD crease pattern as another tool writes it (millimetres without frame_unit, lower-case
    assignments, triangles, no fold angles) plus its folded frame: refold needs no TARGET."""
    from fabkit.cutfiles.creases import crease_assignment
    from fabkit.mesh import PolyMesh
    from fabkit.unfold import develop

    V, F = base
    panel = PolyMesh(V, F)
    flat = np.column_stack([develop(panel).uv, np.zeros(len(V))])
    a = crease_assignment(panel)
    sides = {(int(u), int(v)): c for (u, v), c in zip(panel.edges.tolist(), a.edges_assignment.tolist())}
    path = fold_other_tool(tmp_path / "cp.fold", flat * 1000, triangulated(F, seed=2), sides, lower=True,
                           frames=[V * 1000])
    assert main(["refold", str(path), "-o", str(tmp_path / "seq.fold"), "--units", "mm", "--drive", "all",
                 "--frames", "3", "-q"]) == 0
    seq = load_fold(tmp_path / "seq.fold")
    last = seq.frames[-1].vertices_coords
    e = seq.edges_vertices
    size = float(np.linalg.norm(np.ptp(V, axis=0)))
    np.testing.assert_allclose(np.linalg.norm(last[e[:, 0]] - last[e[:, 1]], axis=1),
                               np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1), rtol=0, atol=1e-9 * size)
    # the crease pattern's valley crease is kept as V
    assert np.sum(seq.edges_assignment == "V") >= np.sum(a.edges_assignment == "V")


# ---- the same plain panel as FOLD (another tool's conventions) and as .3dm, through every stage ----

def _variant_panel():
    """A two-crease reflect panel without tags (60 deg), its M/V per edge (the designer's letters)."""
    from structure_panels import plain, reflect_tagged, true_creases

    tagged = reflect_tagged(2, 60.0)
    mesh = plain(tagged)
    truth = true_creases(tagged)
    strip = np.asarray(tagged.face_data["strip"])
    ef = tagged.edge_faces[truth]
    row = np.minimum(strip[ef[:, 0]], strip[ef[:, 1]])
    letters = {(int(a), int(b)): ("V" if r == 0 else "M") for (a, b), r in zip(tagged.edges[truth].tolist(),
                                                                           row.tolist())}
    return np.asarray(mesh.vertices), mesh.faces_list(), letters


def _through_every_stage(d, src, cell):
    """relax -> unfold -> refold -> toolpath -> check with no flags; (clamped faces, grip face, side,
    joints (W, 6), check ok)."""
    steps = [["relax", str(src), "-o", str(d / "rel.obj")], ["unfold", str(d / "rel.obj"), "-o", str(d / "flat.obj")],
             ["refold", str(d / "flat.obj"), str(d / "rel.obj"), "-o", str(d / "seq.fold"), "--frames", "5"],
             ["toolpath", str(d / "seq.fold"), "--cell", cell, "-o", str(d / "path.json")],
             ["check", str(d / "path.json"), "--cell", cell, "-o", str(d / "check.json")]]
    for cmd in steps:
        assert main([*cmd, "-q"]) == 0, cmd[0]
    path = json.loads((d / "path.json").read_text())
    return (path["holds"]["clamped_faces"], path["grip"]["face"], path["grip"].get("side", "front"),
            np.array([w["q"] for w in path["waypoints"]]), json.loads((d / "check.json").read_text())["ok"])


CELL = str(__import__("pathlib").Path(__file__).resolve().parent.parent / "cells" / "ur5e_bench.toml")


@pytest.fixture(scope="module")
def obj_program(tmp_path_factory):
    V, F, _ = _variant_panel()
    d = tmp_path_factory.mktemp("obj-program")
    return _through_every_stage(d, plain_obj(d / "panel.obj", V, F), CELL)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["fold", "3dm"])
def test_fold_and_3dm_panels_program_as_the_obj(tmp_path, obj_program, fmt):
    """The FOLD (shuffled, lower-case M/V/B/F letters, faces_vertices only, no fabkit keys) and the
    .3dm (rhino3dm, metres) of the same panel give the OBJ's clamp, grip face and program (up to
    the shuffle of the FOLD's faces)."""
    V, F, letters = _variant_panel()
    if fmt == "fold":
        S, G, perm = shuffled(V, F)
        new_id = np.argsort(perm)
        mine = {tuple(sorted((int(new_id[a]), int(new_id[b])))): c for (a, b), c in letters.items()}
        src = fold_other_tool(tmp_path / "panel.fold", S, G, mine, unit="m", lower=True)
        text = src.read_text()
        assert "fabkit" not in text and '"m"' in text and '"v"' in text
        face_of = {tuple(sorted(g)): k for k, g in enumerate(G)}
        old_of_new = {face_of[tuple(sorted(int(new_id[v]) for v in f))]: k for k, f in enumerate(F)}
    else:
        src = rhino_3dm(tmp_path / "panel.3dm", V, F, unit="Meters")
        old_of_new = {k: k for k in range(len(F))}
    clamped, grip, side, q, ok = _through_every_stage(tmp_path, src, CELL)
    clamped0, grip0, side0, q0, ok0 = obj_program
    assert ok and ok0 and side == side0 == "front"
    assert [old_of_new[f] for f in clamped] == clamped0 and old_of_new[grip] == grip0
    assert q.shape == q0.shape
    np.testing.assert_allclose(q, q0, rtol=0, atol=1e-9)


def test_a_crease_patterns_own_mountains_and_valleys_reach_info(tmp_path):
    """A flat FOLD crease pattern with no folded frame: `fabkit info` names its creases with the
    file's own M and V (the geometry is flat: it cannot tell), and swapped letters are reported
    swapped."""
    from fabkit.mesh import PolyMesh
    from fabkit.unfold import develop

    V, F, letters = _variant_panel()
    flat = np.column_stack([develop(PolyMesh(V, F)).uv, np.zeros(len(V))])
    swap = {"M": "V", "V": "M"}
    for name, given, want in (("cp.fold", letters, ("V", "M")),
                              ("swapped.fold", {e: swap[c] for e, c in letters.items()}, ("M", "V"))):
        path = fold_other_tool(tmp_path / name, flat, F, given, unit="m")
        assert main(["info", str(path), "--report", str(tmp_path / "info.json"), "-q"]) == 0
        creases = json.loads((tmp_path / "info.json").read_text())["structure"]["creases"]
        assert [(c["M"], c["V"], c["U"]) for c in creases] == [
            (12 * (w == "M"), 12 * (w == "V"), 0) for w in want]
