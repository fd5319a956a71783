"""The first panel of a small pleated vault and its relaxed, unfolded geometry: the production
set-up tests' panel (a panel of the installation the production bench runs, at test size)."""
from __future__ import annotations

import numpy as np


def first_vault_panel():
    """(panel, its `fabkit.panels.workflow` result) of a 2-row, 8-column pleated vault in 2 panels."""
    from fabkit.generate.pleated import pleated_vault
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.surface import GridSurface, grid_from_topology
    from fabkit.panels.workflow import PanelsOptions, run_panels

    mesh = pleated_vault(rows=2, length=0.5, radius=0.6, arc=np.radians(60.0), fold=np.radians(40.0), columns=8,
                         rows_per_band=8)
    index, _ = grid_from_topology(mesh)
    layout = layout_panels(GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), cols=2,
                           columns_per_panel=4)
    geo = run_panels(layout, PanelsOptions())
    panel = layout.panels[0]
    return panel, geo.results[panel.id]
