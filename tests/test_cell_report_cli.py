"""`fabkit cell --mjcf` loads in MuJoCo; `fabkit report DIR` works for any run folder."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from fabkit.cli import main

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("cell", ["ur5e_bench.toml", "ur10e_fold_table.toml"])
def test_cell_mjcf_loads_in_mujoco(tmp_path, cell, capsys):
    import mujoco

    from robot.cell import load_cell
    from sim.model import build_cell_model

    out = tmp_path / "cell.xml"
    assert main(["cell", str(ROOT / "cells" / cell), "--mjcf", str(out), "--report", str(tmp_path / "r.json")]) == 0
    m = mujoco.MjModel.from_xml_path(str(out))
    ref, names = build_cell_model(load_cell(ROOT / "cells" / cell))
    assert (m.nbody, m.ngeom, m.njnt) == (ref.nbody, ref.ngeom, ref.njnt)
    for j in names.joints:
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) >= 0
    assert json.loads((tmp_path / "r.json").read_text())["joints"] == 6


def test_cell_mjcf_refuses_other_suffixes(tmp_path):
    assert main(["cell", str(ROOT / "cells" / "ur5e_bench.toml"), "--mjcf", str(tmp_path / "c.mjb")]) == 2
    assert not (tmp_path / "c.mjb").exists()


def test_report_for_a_run_that_is_not_the_demo(tmp_path, capsys):
    from fabkit.generate.reflect import reflect_panel
    from fabkit.io.obj import save_obj

    save_obj(reflect_panel(columns=8, rows=2), tmp_path / "p.obj")
    assert main(["relax", str(tmp_path / "p.obj"), "-o", str(tmp_path / "r.obj"), "-q",
                 "--report", str(tmp_path / "relax.json")]) == 0
    assert main(["unfold", str(tmp_path / "r.obj"), "-o", str(tmp_path / "f.obj"), "-q", "--png",
                 str(tmp_path / "error.png"), "--report", str(tmp_path / "unfold.json")]) == 0
    (tmp_path / "notes.json").write_text('{"not": "a fabkit report"}')
    capsys.readouterr()
    assert main(["report", str(tmp_path)]) == 0
    assert "2 stage report(s) (relax, unfold)" in capsys.readouterr().out
    page = (tmp_path / "report.html").read_text()
    assert "<td>relax</td><td class='pass'>pass</td>" in page and "<td>unfold</td>" in page
    assert "data:image/png;base64" in page and "error.png" in page and "notes.json" in page


def test_report_without_reports_exits_1_and_missing_dir_2(tmp_path):
    assert main(["report", str(tmp_path)]) == 1
    assert (tmp_path / "report.html").exists()
    assert main(["report", str(tmp_path / "nope")]) == 2
