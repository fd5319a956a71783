"""fabkit: curved-crease folded panels from coarse mesh to robot fold program.

The public API is the pipeline, one typed function per stage in `fabkit.pipeline` (docs/api.md):
`load` / `generate` -> `relax` -> `unfold` -> `refold` -> `plan` -> `check` -> `send`, each
returning a frozen result (`fabkit.results`) with `ok`, `problems` and `to_json()`:

    import fabkit.pipeline as fk
    relaxed = fk.relax(fk.load("panel.obj", units="mm"))

The stages live in their own namespace because `fabkit.relax`, `fabkit.unfold`, `fabkit.refold` and
`fabkit.generate` are the geometry subpackages they call. Units: metres and radians inside.
`import fabkit` loads no numpy, robot or sim code; the stages import what they need when called.
"""
from fabkit import pipeline
from fabkit.errors import FabkitError, InputError, ToleranceError
from fabkit.results import Checked, Flat, Folds, Panel, Program, Relaxed, Sent

__version__ = "0.1.0"
__all__ = ["pipeline", "Panel", "Relaxed", "Flat", "Folds", "Program", "Checked", "Sent",
           "FabkitError", "InputError", "ToleranceError", "__version__"]
