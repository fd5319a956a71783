"""Offscreen pictures of the cell: a PNG of one configuration, an MP4 of a whole program.

MuJoCo picks its OpenGL backend from `MUJOCO_GL` when `mujoco` is first imported, so
`select_gl_backend()` must run before anything imports mujoco (the CLI calls it first thing). This
module therefore imports mujoco only inside its functions. Backends: EGL (headless, Mesa llvmpipe
works without a GPU), then OSMesa where the project's setup installed it; `Renderer.close()` is
always called explicitly (its `__del__` prints a traceback at interpreter exit otherwise).
"""
from __future__ import annotations

import math
import os

import numpy as np

from fabkit.errors import InputError
from fabkit.io.atomic import atomic_path
from sim.gl_backend import select_gl_backend

__all__ = ["select_gl_backend", "render_frames", "write_png", "write_mp4", "camera_for_cell", "view", "project_points",
           "set_arm_qpos"]


def camera_for_cell(cell):
    """A free camera looking at the robot and its work area (0.25, 0.25) m into the panel frame,
    from the side and above, far enough to see both."""
    import mujoco

    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    base = np.asarray(cell.robot.base_pose)[:3, 3]
    work = (np.asarray(cell.fixture) @ np.array([0.25, 0.25, 0.0, 1.0]))[:3]
    cam.lookat[:] = 0.5 * (base + work) + np.array([0.0, 0.0, 0.15])
    cam.distance = 1.2 + 1.6 * float(np.linalg.norm(work[:2] - base[:2]))
    reach = work[:2] - base[:2]
    # look across the robot-to-work line from its right-hand side, a little from the work end
    cam.azimuth = float(np.degrees(np.arctan2(reach[1], reach[0]))) + 120.0
    cam.elevation = -25.0
    return cam


def project_points(scene, points, width: int, height: int) -> np.ndarray:
    """Pixel (column, row) of world points (P, 3) in a frame rendered from MuJoCo scene `scene`
    (`renderer.scene` after `update_scene`): its two eye cameras averaged, as MuJoCo renders a mono
    picture, and the frustum's half width set by the frame's aspect ratio, as its renderer sets it."""
    cams = [scene.camera[0], scene.camera[1]]
    pos = np.mean([np.asarray(c.pos, np.float64) for c in cams], axis=0)
    fwd = np.mean([np.asarray(c.forward, np.float64) for c in cams], axis=0)
    up = np.mean([np.asarray(c.up, np.float64) for c in cams], axis=0)
    fwd, up = fwd / np.linalg.norm(fwd), up / np.linalg.norm(up)
    glcam = cams[0]
    right = np.cross(fwd, up)
    v = np.asarray(points, np.float64).reshape(-1, 3) - pos
    z = v @ fwd
    near, bottom, top = float(glcam.frustum_near), float(glcam.frustum_bottom), float(glcam.frustum_top)
    half = 0.5 * width / height * (top - bottom)
    x = (v @ right) * near / z
    y = (v @ up) * near / z
    centre = float(np.mean([c.frustum_center for c in cams]))
    col = (x - (centre - half)) / (2 * half) * width
    row = (top - y) / (top - bottom) * height
    return np.column_stack([col, row])


def set_arm_qpos(model, cell, data, q) -> None:
    """Joint positions of every arm in the model: `q` (6,) for the first arm (the others at their
    `home`) or one row of every arm's joints (6 x arms) in the model's joint order."""
    q = np.asarray(q, np.float64).ravel()
    if len(q) == model.nq:
        data.qpos[:] = q
        return
    data.qpos[:6] = q[:6]
    homes = [np.asarray(m.home, np.float64) for _, m in getattr(cell, "extra_arms", ())]
    for i, home in enumerate(homes[: (model.nq - 6) // 6]):
        data.qpos[6 + 6 * i:12 + 6 * i] = home


def render_frames(model, cell, configs, *, panel=None, states=None, width: int = 640, height: int = 480,
                  highlight=(), camera=None, face_colours=None, overlay=None, on_scene=None):
    """Yield RGB frames (height, width, 3) uint8 for joint configurations `configs` (k, 6), or (k,
    6 x arms) for a model with every arm (`set_arm_qpos`; a (k, 6) row puts the other arms at home).

    `states`: fold state per configuration (poses the panel's mocap pieces); `highlight`: geom
    names drawn red (e.g. a collision pair; every piece of a split capsule). `face_colours(k)` ->
    {geom name: rgba} for frame k (the held faces, `sim.hold_colours`); every panel face not named
    is drawn in the plain panel colour. `overlay(frame, k)` -> frame draws on the picture (a
    legend); `on_scene(k, scene)` sees MuJoCo's scene of frame k (its camera, for `project_points`).
    """
    import mujoco

    if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
        raise ValueError(f"frame {width}x{height} exceeds the model's offscreen buffer")
    rgba = model.geom_rgba.copy()
    try:
        from sim.arm import part_name
        from sim.hold_colours import PLAIN_RGBA

        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom)]
        gid = {n: g for g, n in enumerate(names)}
        faces = [g for g, n in enumerate(names) if n.startswith("face_")]
        if face_colours is not None:
            rgba[faces] = PLAIN_RGBA
        wanted = set(highlight)
        red = [g for g, n in enumerate(names) if part_name(n) in wanted]
        base = rgba.copy()
        base[red] = [0.9, 0.1, 0.1, 1.0]
        model.geom_rgba[:] = base
        data = mujoco.MjData(model)
        cam = camera or camera_for_cell(cell)
        try:
            renderer = mujoco.Renderer(model, height=height, width=width)
        except Exception as exc:  # no usable OpenGL context: say which backend failed
            raise InputError(f"cannot render offscreen with MUJOCO_GL={os.environ.get('MUJOCO_GL', '(unset)')}: "
                             f"{type(exc).__name__}: {exc}", source="--render") from None
        try:
            for k, q in enumerate(np.asarray(configs, dtype=np.float64).reshape(len(configs), -1)):
                set_arm_qpos(model, cell, data, q)
                if panel is not None:
                    s = 0.0 if states is None else float(states[k])
                    data.mocap_pos[:], data.mocap_quat[:] = panel.poses_at(s)
                if face_colours is not None:
                    model.geom_rgba[faces] = base[faces]
                    for name, c in face_colours(k).items():
                        if name in gid and gid[name] not in red:
                            model.geom_rgba[gid[name]] = c
                mujoco.mj_forward(model, data)
                renderer.update_scene(data, camera=cam)
                if on_scene is not None:
                    on_scene(k, renderer.scene)
                frame = renderer.render().copy()
                yield frame if overlay is None else overlay(frame, k)
        finally:
            renderer.close()
    finally:
        model.geom_rgba[:] = rgba


def write_png(path, frame: np.ndarray) -> None:
    """Write one RGB frame as PNG (atomically)."""
    import imageio.v3 as iio

    with atomic_path(path) as tmp:
        iio.imwrite(tmp, frame, extension=".png")


def write_mp4(path, frames, fps: int = 30) -> int:
    """Write RGB frames as an H.264 MP4 (atomically, through imageio-ffmpeg); returns the frame count."""
    import imageio.v2 as imageio

    n = 0
    with atomic_path(path) as tmp:
        writer = imageio.get_writer(str(tmp), format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                    quality=7, macro_block_size=16, ffmpeg_log_level="error")
        try:
            for frame in frames:
                writer.append_data(frame)
                n += 1
        finally:
            writer.close()
    return n


def movie_indices(dt: np.ndarray, fps: int = 30, max_frames: int = 240) -> tuple[np.ndarray, float]:
    """Indices of the configurations to show at `fps` in program time (sped up to fit `max_frames`).

    `dt` (M,): time from the previous configuration (NaN = a jump, shown as one frame). Returns the
    indices and the speed-up factor.
    """
    step = np.where(np.isfinite(dt) & (dt > 0), dt, 0.0)
    t = np.cumsum(step)
    duration = float(t[-1]) if len(t) else 0.0
    n = int(min(max_frames, max(2, math.ceil(duration * fps))))
    speedup = max(1.0, duration * fps / max_frames) if duration > 0 else 1.0
    idx = np.searchsorted(t, np.linspace(0.0, duration, n), side="left")
    return np.clip(idx, 0, len(t) - 1), speedup


def view(model, cell, configs, *, panel=None, states=None, dt=None) -> None:  # pragma: no cover - needs a display
    """Play the configurations in MuJoCo's interactive viewer (needs a display)."""
    import time

    import mujoco
    import mujoco.viewer

    data = mujoco.MjData(model)
    with mujoco.viewer.launch_passive(model, data) as v:
        for k, q in enumerate(np.asarray(configs).reshape(-1, 6)):
            if not v.is_running():
                break
            data.qpos[:] = q
            if panel is not None:
                data.mocap_pos[:], data.mocap_quat[:] = panel.poses_at(0.0 if states is None else float(states[k]))
            mujoco.mj_forward(model, data)
            v.sync()
            step = 0.0 if dt is None or not np.isfinite(dt[k]) else float(dt[k])
            time.sleep(min(step, 0.1))
        while v.is_running():
            time.sleep(0.05)
