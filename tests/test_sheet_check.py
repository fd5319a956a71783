"""The sheet in the check: fold-load verdicts per state through `fabkit check` and `fk.check`, the
panel posed in the compensated states with the sheet's thickness, and the send interlock."""
import json

import numpy as np
import pytest

from fabkit.cli import main as fabkit_main
from fabkit.io.fold import load_fold
from fabkit.sheet.creases import panel_creases

from sheet_panels import CELL, GROOVED, crease_600_fold, plan as _plan_to


@pytest.fixture(scope="module")
def crease_600(tmp_path_factory):
    d = tmp_path_factory.mktemp("crease600")
    (crease,) = panel_creases(load_fold(crease_600_fold(d)))
    assert crease.length == pytest.approx(0.6, abs=0.005)  # the 600 mm crease
    return d


def _plan(d, name, *sheet):
    return _plan_to(d / "seq.fold", d / f"{name}.json", *sheet)


def _check(path, *extra):
    import uuid

    out = path.with_name(f"{path.stem}.{uuid.uuid4().hex[:8]}.check.json")
    rc = fabkit_main(["check", str(path), "--cell", CELL, "-o", str(out), "-q", *extra])
    return rc, (json.loads(out.read_text()) if out.exists() else None)


@pytest.fixture(scope="module")
def plain(crease_600):
    return _plan(crease_600, "plain", "--material", "5052-H32", "--thickness", "1mm")


@pytest.fixture(scope="module")
def grooved(crease_600):
    return _plan(crease_600, "grooved", *GROOVED)


def test_unscored_600_mm_crease_fails_fabkit_check_naming_crease_and_remedy(plain):
    rc, rep = _check(plain)
    assert rc == 1 and not rep["ok"]
    loads = [p for p in rep["problems"] if p["kind"] == "load"]
    assert loads and all(p["detail"].startswith("crease 0, fold states 1,2,3,4:") for p in loads)
    assert [p for p in rep["problems"] if p["kind"] != "load"] == []  # the motion itself is clean
    wrist = next(p for p in loads if "wrist couple" in p["subject"])
    assert "groove the crease to a ligament of at most" in wrist["detail"] and "ur10e" in wrist["detail"]
    assert wrist["value"] == pytest.approx(36.6 / 28.0, abs=0.01)  # 36.6 N m of the wrist's 28
    assert any("push instead of pull" in p["detail"] for p in loads)  # the valley makes the cup pull
    L = rep["loads"]
    assert L["arm"] == "ur5e" and not L["ok"] and L["recorded"] and L["sheet"]["crease_preparation"] == "plain"
    assert [s["state"] for s in L["states"]] == [1, 2, 3, 4]
    for st in L["states"]:
        first, last = st["waypoints"]
        assert 0 < first <= last and not st["ok"]
        for c in st["checks"]:
            assert c["moment_nm"] == pytest.approx(36.6, abs=0.1)
            assert c["ratio"] == pytest.approx(c["demand"] / c["capacity"], rel=1e-12)
            assert c["ok"] == (c["demand"] <= c["capacity"])


def test_the_same_crease_grooved_to_0_4_mm_passes_fabkit_check(grooved):
    rc, rep = _check(grooved)
    assert rc == 0 and rep["ok"] and rep["problems"] == []
    L = rep["loads"]
    assert L["ok"] and L["sheet"]["crease"] == "grooved to a 0.4 mm ligament"
    checks = [c for st in L["states"] for c in st["checks"]]
    assert {c["check"] for c in checks} == {"wrist couple", "fold force + payload weight", "cup pull", "cup tilt"}
    assert all(c["ok"] and c["ratio"] <= 1 for c in checks)
    assert max(c["moment_nm"] for c in checks) == pytest.approx(36.6 * 0.4 ** 2, abs=0.05)  # m_p ~ t_l^2


def test_a_failed_load_check_blocks_the_send(plain):
    from robot.cell import load_cell
    from robot.interlock import CheckFailedError, clear_for_send
    from robot.toolpath import Toolpath

    rc, rep = _check(plain)
    assert rc == 1
    with pytest.raises(CheckFailedError, match="load crease 0"):
        clear_for_send(Toolpath.load(plain), rep, load_cell(CELL), base_dir=plain.parent)


def test_check_refuses_another_sheet_than_the_program_was_planned_for(plain):
    rc, rep = _check(plain, "--material", "1100-H14", "--thickness", "0.5mm")
    assert rc == 2 and rep is None
    rc, _ = _check(plain, "--material", "none")
    assert rc == 2
    rc, rep = _check(plain, "--material", "5052-H32", "--thickness", "1mm")  # the same sheet: as without
    assert rc == 1 and rep["loads"]["recorded"]


def test_check_material_on_a_rigid_program_adds_the_loads_and_says_so(crease_600):
    rigid = _plan(crease_600, "rigid")
    rc, rep = _check(rigid)
    assert rc == 0 and rep["loads"] is None
    rc, rep = _check(rigid, "--material", "5052-H32", "--thickness", "1mm")
    assert rc == 1 and not rep["loads"]["recorded"]
    assert any("planned rigid" in n for n in rep["notes"])
    assert any(p["kind"] == "load" and "crease 0" in p["detail"] for p in rep["problems"])


def test_the_panel_is_checked_in_the_compensated_states_with_the_sheets_thickness(crease_600, tmp_path):
    from robot.cell import load_cell
    from robot.sheet_program import compensated_states, sheet_of_toolpath
    from robot.toolpath import Toolpath
    from sim.check import run_toolpath_check
    from sim.panel import panel_from_fold

    path = _plan(crease_600, "thick", "--material", "5052-H32", "--thickness", "2mm")
    tp = Toolpath.load(path)
    spec = sheet_of_toolpath(tp)
    assert spec.thickness == pytest.approx(0.002) and spec.inside_radius == pytest.approx(0.003)
    res = run_toolpath_check(path, load_cell(CELL))
    assert res.panel.pieces.thickness == pytest.approx(0.002)
    design = load_fold(crease_600 / "seq.fold")
    comp = compensated_states(design, spec).model
    from robot.panel_placement import placed_cell, placement_of

    cell = placed_cell(load_cell(CELL), placement_of(tp.extra))  # where the check poses the panel
    grip = tp.extra["grip"]["face"]
    want = panel_from_fold(comp, cell.fixture, grip_face_id=grip, thickness=0.002)
    as_designed = panel_from_fold(design, cell.fixture, grip_face_id=grip, thickness=0.002)
    np.testing.assert_allclose(res.panel.pos, want.pos, atol=1e-12)
    assert np.abs(as_designed.pos[-1] - want.pos[-1]).max() > 1e-3  # the overbend moves the faces by mm


def _table(page: str, table_id: str) -> list[list[str]]:
    """The rows (cell texts) of the table with this id, read with the standard HTML parser."""
    from html.parser import HTMLParser

    class Rows(HTMLParser):
        def __init__(self):
            super().__init__()
            self.inside, self.rows, self.cell = False, [], None

        def handle_starttag(self, tag, attrs):
            if tag == "table" and dict(attrs).get("id") == table_id:
                self.inside = True
            elif self.inside and tag == "tr":
                self.rows.append([])
            elif self.inside and tag in ("td", "th"):
                self.cell = ""

        def handle_endtag(self, tag):
            if tag == "table":
                self.inside = False
            elif self.inside and tag in ("td", "th"):
                self.rows[-1].append(self.cell.strip())
                self.cell = None

        def handle_data(self, data):
            if self.cell is not None:
                self.cell += data

    p = Rows()
    p.feed(page)
    return p.rows


def test_report_html_shows_design_and_programmed_angles_and_the_load_verdicts(plain, tmp_path):
    import shutil

    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(plain, run / "path.json")
    rc, rep = _check(plain)
    (run / "check.json").write_text(json.dumps(rep))
    assert fabkit_main(["report", str(run), "-q"]) == 0
    page = (run / "report.html").read_text()
    doc = json.loads(plain.read_text())
    angles = _table(page, "sheet-angles")
    assert angles[0][:4] == ["state", "crease", "design angle [deg]", "programmed angle [deg]"]
    want = [(st["state"], c) for st in doc["sheet"]["states"] for c in st["creases"]]
    assert len(angles) - 1 == len(want)
    for row, (s, c) in zip(angles[1:], want):
        assert row[:2] == [str(s), c["crease"]]
        assert float(row[2]) == pytest.approx(c["design_deg"], abs=0.005)
        assert float(row[3]) == pytest.approx(c["programmed_deg"], abs=0.005)
    assert float(angles[-1][3]) > float(angles[-1][2])  # overbent
    loads = _table(page, "sheet-loads")
    checks = [(st["state"], c) for st in rep["loads"]["states"] for c in st["checks"]]
    assert len(loads) - 1 == len(checks)
    for row, (s, c) in zip(loads[1:], checks):
        assert row[0] == str(s) and row[1] == c["crease"] and row[2] == c["check"]
        assert row[7] == ("pass" if c["ok"] else "fail")
        assert float(row[4].split()[0]) == pytest.approx(c["demand"], abs=0.05)
        if not c["ok"]:
            assert row[8] == c["remedy"]


@pytest.mark.parametrize("surface", ["top", "bottom"])
def test_the_cup_sits_on_the_sheets_top_face_and_the_slab_lies_behind_it(crease_600, surface):
    """2 mm sheet: the grip face's collision slab spans [0, t] ahead of the TCP along the tool axis,
    whichever surface of the sheet the FOLD's faces are (the standoff grows by t for the bottom)."""
    from scipy.spatial.transform import Rotation

    from robot.cell import load_cell, pose_to_matrix
    from robot.toolpath import Toolpath
    from sim.check import run_toolpath_check

    path = _plan(crease_600, f"ds-{surface}", "--material", "5052-H32", "--thickness", "2mm",
                 "--design-surface", surface)
    tp = Toolpath.load(path)
    assert tp.extra["sheet"]["design_surface"] == surface
    assert tp.extra["sheet"]["front_face_offset_mm"] == pytest.approx({"top": 0.0, "bottom": 2.0}[surface])
    res = run_toolpath_check(path, load_cell(CELL))
    panel = res.panel
    g = panel.grip_face
    k = next(i for i, w in enumerate(tp.waypoints) if w.op == "grip")
    T = pose_to_matrix(tp.waypoints[k].pose)
    R = Rotation.from_quat(np.asarray(panel.quat[0][g])[[1, 2, 3, 0]]).as_matrix()
    cell = load_cell(CELL)
    W = cell.world_to_base
    corners = (panel.pieces.local_vertices[g] @ R.T + panel.pos[0][g]) @ W[:3, :3].T + W[:3, 3]
    depth = (corners - T[:3, 3]) @ T[:3, 2]  # along the tool's z, into the face
    assert depth.min() == pytest.approx(0.0, abs=2e-5) and depth.max() == pytest.approx(0.002, abs=2e-5)
    if surface == "bottom":
        top = Toolpath.load(_plan(crease_600, "ds-top-ref", "--material", "5052-H32", "--thickness", "2mm"))
        Tt = pose_to_matrix(top.waypoints[k].pose)
        assert (T[:3, 3] - Tt[:3, 3]) @ Tt[:3, 2] == pytest.approx(-0.002, abs=1e-9)  # backed off by t


def test_the_api_plans_and_checks_a_sheet_as_the_commands_do(tmp_path):
    import fabkit.pipeline as fk

    panel = fk.generate("reflect", radius=5.0, arc=6.88, fold=45.0, columns=12)
    folds = fk.refold(fk.unfold(panel), frames=5)  # exactly developable: nothing to relax
    plain = fk.plan(folds, CELL, workdir=tmp_path / "plain", material="5052-H32", thickness="1mm", tool_mass=0.5)
    assert plain.ok and plain.toolpath.extra["sheet"]["crease_preparation"] == "plain"
    assert not plain.details["loads"]["ok"]
    checked = fk.check(plain)
    assert not checked.ok and any("load: crease 0" in p and "remedy: groove the crease" in p for p in checked.problems)
    # the same CHECK.json as fabkit check writes for the program's path.json
    rc, rep = _check(plain.path_file)
    assert rc == 1 and rep["loads"] == json.loads(checked.check_file.read_text())["loads"]
    grooved = fk.plan(folds, CELL, workdir=tmp_path / "grooved", material="5052-H32", thickness=0.001,
                      crease="grooved", ligament="0.4mm", tool_mass=0.5)
    assert grooved.ok and fk.check(grooved).ok
    strict = fk.plan(folds, CELL, workdir=tmp_path / "strict", material="5052-H32", thickness="1mm",
                     check_loads=True)
    assert not strict.ok and strict.path_file is None and "crease 0" in strict.problems[0]
    with pytest.raises(Exception, match="--material"):
        fk.check(plain, material="1100-H14", thickness="0.5mm")


def test_design_surface_needs_a_material(crease_600, capsys):
    out = crease_600 / "ds-rigid.json"
    rc = fabkit_main(["toolpath", str(crease_600 / "seq.fold"), "--cell", CELL, "-o", str(out), "-q",
                      "--design-surface", "bottom"])
    assert rc == 2 and not out.exists() and "--design-surface" in capsys.readouterr().err
