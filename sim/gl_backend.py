"""MuJoCo's OpenGL backend, chosen before mujoco is first imported (it reads `MUJOCO_GL` once).

MuJoCo's default (GLFW) needs a display and costs about 0.3 s to load (pyglfw checks its library
in a subprocess), so every sim module that imports mujoco imports this module first: an explicit
`MUJOCO_GL` is kept; otherwise EGL (or OSMesa) is chosen, which is what offscreen rendering
(`sim.render`) needs anyway. Standard library only: the stand-in's `--help` imports no numpy.
"""
from __future__ import annotations

import ctypes.util
import os
import sys

__all__ = ["select_gl_backend"]


def select_gl_backend() -> str | None:
    """Choose an offscreen OpenGL backend for MuJoCo; returns its name, or None if there is none.

    Respects an explicit `MUJOCO_GL`. Otherwise sets `egl` when libEGL is installed, else `osmesa`
    (with `PYOPENGL_PLATFORM=osmesa`) when libOSMesa is. Once mujoco is imported it can only report
    the backend mujoco picked (None if that is GLFW without a display).
    """
    if "mujoco" in sys.modules:  # too late to choose: report what mujoco picked at import
        context = getattr(sys.modules["mujoco"], "GLContext", None)
        picked = getattr(context, "__module__", "").rsplit(".", 1)[-1]
        if picked in ("egl", "osmesa") or (picked == "glfw" and os.environ.get("DISPLAY")):
            return picked
        return None
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    if ctypes.util.find_library("EGL"):
        os.environ["MUJOCO_GL"] = "egl"
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        return "egl"
    if ctypes.util.find_library("OSMesa"):
        os.environ["MUJOCO_GL"] = "osmesa"
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
        return "osmesa"
    return None


if "mujoco" not in sys.modules:
    select_gl_backend()
