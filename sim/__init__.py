"""MuJoCo side of fabkit: the cell model, the toolpath check, rendering, the controller stand-in.

- `sim.arm`: the UR arm as DH-exact MuJoCo bodies (flange site = `robot.kinematics.fk`).
- `sim.panel`: the panel as one thin convex piece per face, posed per fold state.
- `sim.model.build_cell_model(cell, panel)`: arm + tool + obstacles + panel -> `(MjModel, CellNames)`.
- `sim.check.check_toolpath(toolpath, cell)` / `check_program(...)`: CHECK.json's `CheckReport` (the
  modules it is built from: `sim.interpolate`, `sim.check_events`, `sim.problems`, `sim.toolpath_program`).
- `sim.render`: offscreen PNG/MP4 (call `select_gl_backend()` before anything imports mujoco).
- `sim.programs`: synthetic sweep programs for tests and benchmarks.
- `sim.ursim`: the controller stand-in (its own package).

MuJoCo reads `MUJOCO_GL` once, when it is first imported, and its default (GLFW) needs a display
and costs about 0.3 s to load (pyglfw checks its library in a subprocess). So importing this
package runs `sim.render.select_gl_backend()` before any sim module imports mujoco: an explicit
`MUJOCO_GL` is kept; otherwise EGL (or OSMesa) is chosen, which is what rendering needs anyway.
"""
from sim.render import select_gl_backend as _select_gl_backend

_select_gl_backend()
