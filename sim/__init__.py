"""MuJoCo side of fabkit: the cell model, the toolpath check, rendering, the controller stand-in.

- `sim.arm`: the UR arm as DH-exact MuJoCo bodies (flange site = `robot.kinematics.fk`).
- `sim.panel`: the panel as one thin convex piece per face, posed per fold state.
- `sim.model.build_cell_model(cell, panel)`: arm + tool + obstacles + panel -> `(MjModel, CellNames)`.
- `sim.check.check_toolpath(toolpath, cell)` / `check_program(...)`: CHECK.json's `CheckReport` (the
  modules it is built from: `sim.interpolate`, `sim.check_events`, `sim.problems`, `sim.toolpath_program`).
- `sim.render`: offscreen PNG/MP4 (call `select_gl_backend()` before anything imports mujoco).
- `sim.programs`: synthetic sweep programs for tests and benchmarks.
- `sim.ursim`: the controller stand-in (its own package).

Every module here that imports mujoco imports `sim.gl_backend` first, which picks MuJoCo's
offscreen OpenGL backend before mujoco loads (`select_gl_backend`).
"""
