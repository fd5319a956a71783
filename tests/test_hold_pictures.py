"""Pictures that show what holds the panel: the held faces are drawn in their hold's colour where
they are (the pixel at each held face's projected points has that colour's hue), a face nothing
holds is not, the legend and grip-change banner are drawn, and the record is read for any number
of arms."""
from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np
import pytest

from fabkit.held_faces import grip_changes, held_faces
from sim.hold_colours import ARM_RGBAS, CLAMP_RGBA, JIG_RGBA, hold_roles

ROOT = Path(__file__).resolve().parent.parent
JIG_CELL = str(ROOT / "cells" / "ur10e_jig.toml")


def hue_sat(rgb) -> tuple[float, float]:
    h, s, _ = colorsys.rgb_to_hsv(*(np.asarray(rgb[:3], float) / (255.0 if max(rgb[:3]) > 1 else 1.0)))
    return h, s


def same_hue(pixel, rgba, tol: float = 0.04) -> bool:
    """Shading changes brightness (and saturates), not the hue of a saturated colour."""
    h, s = hue_sat(pixel)
    h0, _ = hue_sat(rgba)
    return s > 0.5 and min(abs(h - h0), 1 - abs(h - h0)) < tol


@pytest.fixture(scope="module")
def gl():
    from test_sim_cli import _gl_probe

    reason = _gl_probe()
    if reason:
        pytest.skip(reason)


@pytest.fixture(scope="module")
def jig_run():
    from test_jigs import planned_jig_program

    from robot.cell import load_cell
    from sim.check import run_toolpath_check

    fold, path = planned_jig_program()
    cell = load_cell(JIG_CELL)
    return run_toolpath_check(path, cell, fold=fold), cell


def test_held_faces_are_drawn_in_their_colour_where_they_are(gl, jig_run, tmp_path):
    import imageio.v3 as iio

    from sim.model import build_cell_model
    from sim.render import project_points, render_frames
    from sim.render_check import face_points, project_scene, render_waypoint

    run, cell = jig_run
    k = [i for i, op in enumerate(run.program.ops) if op == "fold"][5]
    W, H = 320, 240
    out = render_waypoint(run, cell, tmp_path / "w.png", size=(W, H), waypoint=k)
    img = iio.imread(tmp_path / "w.png")
    held = {h["hold"]: h for h in out["held"]}
    assert set(held) == {"clamp", "arm a", "jig wing_pad"}
    assert (held["clamp"]["face"], held["arm a"]["face"], held["jig wing_pad"]["face"]) == (5, 11, 1)
    colours = {"clamp": CLAMP_RGBA, "arm a": ARM_RGBAS[0], "jig wing_pad": JIG_RGBA}
    for label, h in held.items():
        px = [img[int(r), int(c)] for c, r in h["pixels"] if 0 <= c < W and 0 <= r < H]
        hits = sum(same_hue(p, colours[label]) for p in px)
        # the cup covers the middle of the gripped face: its corners show
        assert hits >= (2 if label == "arm a" else len(px) - 1), (label, px)
    # a face nothing holds (the middle strip's other face) is drawn plain, not in any hold's colour
    # (its pixel found through the same camera)
    state = float(run.dense.state[out["config"]])
    scenes = []
    m, _ = build_cell_model(cell, run.panel)
    next(iter(render_frames(m, cell, run.dense.q[out["config"]:out["config"] + 1], panel=run.panel,
                            states=[state], width=W, height=H, face_colours=lambda _: {},
                            on_scene=lambda _, s: scenes.append(project_scene(s)))))
    c, r = project_points(scenes[0], face_points(run.panel, 4, state)[:1], W, H)[0]
    assert not any(same_hue(img[int(r), int(c)], colours[x]) for x in colours)
    # the banner at the bottom names the waypoint; the legend swatches are the hold colours
    assert out["banner"].startswith(f"waypoint {k} (fold)")
    assert np.abs(img[H - 3, W // 2].astype(int) - [255, 250, 210]).max() < 12


def test_the_grip_waypoint_names_the_grip_and_the_movie_shows_each_change(gl, jig_run, tmp_path):
    import imageio.v2 as imageio

    from sim.render_check import render_movie, render_waypoint

    run, cell = jig_run
    g = run.program.ops.index("grip")
    out = render_waypoint(run, cell, tmp_path / "g.png", size=(160, 120), waypoint=g)
    assert out["banner"] == f"waypoint {g}: arm a grips face 11"
    mov = render_movie(run, cell, tmp_path / "m.mp4", size=(96, 64), max_frames=12)
    assert mov["frames"] <= 12 and len(mov["grip_changes"]) == 2 and "releases face 11" in mov["grip_changes"][1]
    reader = imageio.get_reader(str(tmp_path / "m.mp4"), format="FFMPEG")
    try:
        bottoms = [np.asarray(f)[-3, 48].astype(int) for f in reader]
    finally:
        reader.close()
    banner = [np.abs(b - [255, 250, 210]).max() < 25 for b in bottoms]
    assert any(banner) and not all(banner)


def test_the_record_is_read_for_any_number_of_arms():
    record = {"clamped_faces": [4], "arms": {"a": [None, 7, 7, None, 9, 9], "b": [None, None, 12, 12, 12, None]},
              "jigs": {"pad": [1, 1, 1, 1, None, None]}}
    roles = hold_roles(record)
    assert [r for r, _ in roles] == ["clamp", "arm a", "arm b", "jig pad"]
    assert len({c for _, c in roles}) == 4
    assert {(h.label, h.face) for h in held_faces(record, 2)} == {("clamp", 4), ("arm a", 7), ("arm b", 12),
                                                                   ("jig pad", 1)}
    assert [c.text for c in grip_changes(record)] == [
        "waypoint 0: arm a grips face 7", "waypoint 1: arm b grips face 12", "waypoint 2: arm a releases face 7",
        "waypoint 3: arm a grips face 9", "waypoint 4: arm b releases face 12"]


def test_every_arm_of_a_two_arm_cell_is_posed_in_the_pictures():
    """The picture model has every arm; a one-arm row puts the others at their home, a row of every
    arm's joints poses each."""
    import mujoco

    from robot.cell import load_cell
    from sim.render import set_arm_qpos
    from sim.render_check import picture_model

    cell = load_cell(ROOT / "cells" / "dual_ur10e.toml")
    m = picture_model(cell, None)
    assert m.nq == 12
    d = mujoco.MjData(m)
    q_a = np.array([0.1, -1.2, 1.0, -1.4, -1.5, 0.2])
    set_arm_qpos(m, cell, d, q_a)
    assert np.allclose(d.qpos[:6], q_a) and np.allclose(d.qpos[6:], cell.extra_arms[0][1].home)
    both = np.concatenate([q_a, q_a[::-1]])
    set_arm_qpos(m, cell, d, both)
    assert np.allclose(d.qpos, both)
