"""`fabkit check` end to end: planned fold programs in both cells, obstacle variant, refusals, renders."""
import json
import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from fabkit.cli import main as fabkit_main
from fabkit.frames import middle_row_frames
from fabkit.io.fold import save_fold
from fold_fixtures import folded_grid_model
from robot.cell import load_cell, pose_to_matrix
from robot.toolpath import Toolpath, document_sha256, plan_panel

ROOT = Path(__file__).resolve().parent.parent
CELLS = ROOT / "cells"
CELL_FILES = {"ur5e": CELLS / "ur5e_bench.toml", "ur10e": CELLS / "ur10e_fold_table.toml"}


def _grid(clamp_strip, angles_deg):
    """A 3-strip grid (0.5 m x 0.6 m, bounding box at the panel origin like a `fabkit unfold`
    pattern) folded in 8 steps, triangulated with a polygon map like `fabkit refold` writes."""
    return folded_grid_model(n_states=9, angles=[math.radians(a) for a in angles_deg], clamp_strip=clamp_strip,
                             triangulate=True)


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    from robot.holds_record import clamped_faces_of

    """Strip 2 folded up 60 deg about its crease with strip 0 clamped, planned in both cells by the
    toolpath planner (its own grip face choice); and the far wing of a two-wing fold."""
    d = tmp_path_factory.mktemp("check")
    model = _grid(0, [0, 60])
    save_fold(model, d / "grid.fold")
    out = {}
    for name, cell_file in CELL_FILES.items():
        cell = load_cell(cell_file)
        res = plan_panel(cell, middle_row_frames(model), source={"file": "grid.fold"},
                         clamped_faces=clamped_faces_of(model))
        path = d / f"path_{name}.json"
        res.toolpath.save(path)
        out[name] = (cell, res.toolpath, path)
    # both wings up 60 deg around the clamped middle strip; the planner holds the far wing (face 6)
    wings = _grid(1, [60, 60])
    save_fold(wings, d / "wings.fold")
    res = plan_panel(out["ur5e"][0], middle_row_frames(wings), grip_face=6, source={"file": "wings.fold"},
                     clamped_faces=clamped_faces_of(wings))
    res.toolpath.save(d / "path_far.json")
    return d, out


def _check(args, capsys):
    rc = fabkit_main(["check"] + [str(a) for a in args])
    return rc, capsys.readouterr()


@pytest.mark.parametrize("name", ["ur5e", "ur10e"])
def test_planned_fold_program_passes_in_both_cells(planned, name, capsys):
    d, out = planned
    cell, tp, path = out[name]
    rc, cap = _check([path, "--cell", CELL_FILES[name], "-o", d / f"check_{name}.json",
                      "--report", d / f"r_{name}.json"], capsys)
    assert rc == 0, cap.out + cap.err
    js = json.loads((d / f"check_{name}.json").read_text())
    assert js["format"] == "fabkit.check/2" and js["ok"] is True and js["problems"] == []
    assert js["toolpath_sha256"] == tp.sha256
    assert js["panel_faces"] == 15 and js["waypoints"] == len(tp)
    assert js["configs_checked"] > len(tp)
    # the tool stays clear of every face but the one it holds: nothing comes inside the measuring
    # window, which is wider than the cell's clearance
    assert js["min_clearance_m"] is None and js["min_clearance_pair"] is None
    assert js["clearance_window_m"] > js["clearance_limit_m"] == cell.limits.clearance
    assert all(c is None for c in js["along_path"]["clearance_m"])
    assert js["fold"]["path"].endswith("grid.fold") and js["cell_sha256"] == cell.sha256
    assert js["cycle_time_s"] > 0
    rep = json.loads((d / f"r_{name}.json").read_text())
    assert rep["ok"] and rep["configs_per_second"] > 0
    assert "check: ok" in cap.out


def test_far_wing_collides_with_the_arm(planned, capsys):
    """Holding the far wing from inside the valley, the arm reaches over the near wing as it rises."""
    d, _ = planned
    rc, cap = _check([d / "path_far.json", "--cell", CELL_FILES["ur5e"], "-o", d / "far.json"], capsys)
    assert rc == 1
    js = json.loads((d / "far.json").read_text())
    hits = [p for p in js["problems"] if p["kind"] == "collision"]
    assert hits and all(p["pair"][1].startswith("face_") for p in hits)
    tp = Toolpath.load(d / "path_far.json")
    assert {tp.waypoints[p["waypoint"]]["op"] for p in hits} <= {"fold", "release", "retract"}
    assert "collision" in cap.out


def test_obstacle_variant_names_the_pair_and_the_first_waypoint(planned, tmp_path, capsys):
    d, out = planned
    cell, tp, path = out["ur5e"]
    # a 2 cm ball right where the approach move ends (the TCP of waypoint 1)
    ops = [w["op"] for w in tp.waypoints]
    k = ops.index("approach")
    centre = (cell.robot.base_pose @ pose_to_matrix(tp.waypoints[k]["pose"]))[:3, 3]
    data = tomllib.loads(CELL_FILES["ur5e"].read_text())
    data["obstacles"].append({"name": "stray_clamp", "kind": "sphere", "radius": 0.02,
                              "pose": [*centre.tolist(), 0.0, 0.0, 0.0]})
    variant = tmp_path / "variant.toml"
    variant.write_text(_toml(data))
    rc, cap = _check([path, "--cell", variant, "-o", tmp_path / "c.json", "--fold", d / "grid.fold"], capsys)
    assert rc == 1
    js = json.loads((tmp_path / "c.json").read_text())
    assert js["ok"] is False
    first = min((p for p in js["problems"] if p["kind"] == "collision"), key=lambda p: p["waypoint"])
    assert first["waypoint"] == k and first["pair"] == ["suction_cup", "stray_clamp"]
    assert first["detail"].startswith("suction_cup × stray_clamp")
    assert f"waypoint {k}: collision: suction_cup × stray_clamp" in cap.out
    # the clearance figures carry the collision: a negative distance between the named pair, and
    # along the path a measured (not None) clearance at the waypoint that collides
    assert isinstance(js["min_clearance_m"], float) and js["min_clearance_m"] < 0
    assert "stray_clamp" in js["min_clearance_pair"]
    at_k = js["along_path"]["clearance_m"][js["along_path"]["waypoint"].index(k)]
    assert isinstance(at_k, float) and at_k < 0


def _toml(data: dict) -> str:
    """Minimal TOML writer for the cell dictionaries used here (tables, arrays of tables, scalars)."""
    def val(v):
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return repr(float(v)) if isinstance(v, float) else str(v)

    lines = [f"{k} = {val(v)}" for k, v in data.items() if not isinstance(v, (dict, list)) or
             (isinstance(v, list) and not (v and isinstance(v[0], dict)))]
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append(f"[{k}]")
            lines += [f"{kk} = {val(vv)}" for kk, vv in v.items() if not isinstance(vv, list) or not vv
                      or not isinstance(vv[0], dict)]
            for kk, vv in v.items():
                if isinstance(vv, list) and vv and isinstance(vv[0], dict):
                    for t in vv:
                        lines.append(f"[[{k}.{kk}]]")
                        lines += [f"{a} = {val(b)}" for a, b in t.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for t in v:
                lines.append(f"[[{k}]]")
                lines += [f"{a} = {val(b)}" for a, b in t.items()]
    return "\n".join(lines) + "\n"


def test_edited_toolpath_is_refused_with_exit_2(planned, tmp_path, capsys):
    d, out = planned
    _, tp, path = out["ur5e"]
    doc = json.loads(path.read_text())
    doc["waypoints"][3]["q"][0] += 0.1  # edited after planning; stored sha256 kept
    bad = tmp_path / "edited.json"
    bad.write_text(json.dumps(doc))
    rc, cap = _check([bad, "--cell", CELL_FILES["ur5e"], "-o", tmp_path / "c.json"], capsys)
    assert rc == 2 and "sha256 does not match" in cap.err and str(bad) in cap.err
    assert len(cap.err.strip().splitlines()) == 1
    assert not (tmp_path / "c.json").exists()


def test_wrong_robot_wrong_fold_and_missing_files_exit_2(planned, tmp_path, capsys):
    d, out = planned
    _, _, path10 = out["ur10e"]
    rc, cap = _check([path10, "--cell", CELL_FILES["ur5e"], "-o", tmp_path / "c.json"], capsys)
    assert rc == 2 and "ur10e" in cap.err and "ur5e" in cap.err
    # a FOLD file whose bytes differ from the one planned from
    _, _, path5 = out["ur5e"]
    save_fold(_grid(0, [0, 50]), tmp_path / "grid.fold")
    doc = json.loads(path5.read_text())
    doc["source"]["sha256"] = "0" * 64
    tp = Toolpath.from_json({**doc, "sha256": document_sha256(doc)})  # re-sealed after the edit
    tp.save(tmp_path / "p.json")
    rc, cap = _check([tmp_path / "p.json", "--cell", CELL_FILES["ur5e"], "-o", tmp_path / "c.json"], capsys)
    assert rc == 2 and "fold states changed since planning" in cap.err
    rc, cap = _check([path5, "--cell", CELL_FILES["ur5e"], "-o", tmp_path / "c.json", "--fold",
                      tmp_path / "nope.fold"], capsys)
    assert rc == 2 and "nope.fold" in cap.err
    rc, cap = _check([tmp_path / "missing.json", "--cell", CELL_FILES["ur5e"], "-o", tmp_path / "c.json"], capsys)
    assert rc == 2 and "missing.json" in cap.err
    rc, cap = _check([path5, "--cell", CELL_FILES["ur5e"], "-o", tmp_path / "c.json", "--render", "x.gif"], capsys)
    assert rc == 2 and "--render" in cap.err
    assert not (tmp_path / "c.json").exists()


def _gl_probe() -> str | None:
    """None if an offscreen GL backend renders here, else the reason (from a clean subprocess)."""
    code = ("import sys; sys.path.insert(0, %r)\n"
            "from sim.render import select_gl_backend\n"
            "b = select_gl_backend()\n"
            "import mujoco\n"
            "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\".1\"/></worldbody></mujoco>')\n"
            "r = mujoco.Renderer(m, 16, 16); r.render(); r.close(); print(b)\n") % str(ROOT)
    try:
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        return "offscreen GL probe timed out"
    if p.returncode != 0:
        lines = (p.stderr or p.stdout).strip().splitlines()
        return f"no offscreen OpenGL backend: {lines[-1] if lines else 'renderer failed'}"
    return None


@pytest.fixture(scope="module")
def gl():
    reason = _gl_probe()
    if reason:
        pytest.skip(reason)


def _run_cli(args, timeout=120):
    env = dict(os.environ)
    if env.get("MUJOCO_GL") == "glfw":  # let the command pick an offscreen backend itself
        del env["MUJOCO_GL"]
    return subprocess.run([sys.executable, "-m", "fabkit", "check"] + [str(a) for a in args], capture_output=True,
                          text=True, timeout=timeout, cwd=ROOT, env=env)


def test_render_png_of_a_waypoint_and_mp4_of_the_program(gl, planned, tmp_path):
    import imageio.v3 as iio

    d, out = planned
    _, tp, path = out["ur10e"]
    k = [w["op"] for w in tp.waypoints].index("grip")
    png = tmp_path / "w.png"
    p = _run_cli([path, "--cell", CELL_FILES["ur10e"], "-o", tmp_path / "c.json", "--render", png, "--waypoint", k,
                  "--size", "96x64"])
    assert p.returncode == 0, p.stderr
    img = iio.imread(png)
    assert img.shape == (64, 96, 3) and img.std() > 5  # a picture, not a blank frame
    assert "Traceback" not in p.stderr
    mp4 = tmp_path / "prog.mp4"
    p = _run_cli([path, "--cell", CELL_FILES["ur10e"], "-o", tmp_path / "c.json", "--render", mp4, "--size", "64x48",
                  "--frames", "8", "-q"])
    assert p.returncode == 0, p.stderr
    import imageio.v2 as imageio

    reader = imageio.get_reader(str(mp4), format="FFMPEG")
    try:
        n = sum(1 for _ in reader)
    finally:
        reader.close()
    assert 2 <= n <= 8


def test_view_without_a_display_is_refused_before_checking(planned, tmp_path, capsys, monkeypatch):
    d, out = planned
    monkeypatch.delenv("DISPLAY", raising=False)
    rc, cap = _check([out["ur5e"][2], "--cell", CELL_FILES["ur5e"], "-o", tmp_path / "c.json", "--view"], capsys)
    assert rc == 2 and "--view" in cap.err and not (tmp_path / "c.json").exists()


def test_checking_in_another_cell_is_noted(planned, tmp_path, capsys):
    d, out = planned
    text = CELL_FILES["ur5e"].read_text().replace('name = "ur5e_bench"', 'name = "ur5e_bench_copy"')
    assert "ur5e_bench_copy" in text
    (tmp_path / "copy.toml").write_text(text)
    rc, cap = _check([out["ur5e"][2], "--cell", tmp_path / "copy.toml", "-o", tmp_path / "c.json",
                      "--fold", d / "grid.fold"], capsys)
    js = json.loads((tmp_path / "c.json").read_text())
    assert rc == 0 and any("planned for cell 'ur5e_bench'" in n for n in js["notes"])
