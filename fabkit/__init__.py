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
from fabkit.errors import FabkitError, InputError, ToleranceError

__version__ = "0.1.0"
__all__ = ["pipeline", "Panel", "Relaxed", "Flat", "Folds", "Program", "Checked", "Sent",
           "FabkitError", "InputError", "ToleranceError", "__version__"]

_RESULTS = ("Panel", "Relaxed", "Flat", "Folds", "Program", "Checked", "Sent")


def __getattr__(name: str):
    """`fabkit.pipeline` and the result types, imported on first use (PEP 562): every `fabkit SUB`
    imports this package first, and `fabkit SUB --help` should not pay for the dataclasses."""
    import importlib

    if name == "pipeline":
        return importlib.import_module("fabkit.pipeline")
    if name in _RESULTS:
        return getattr(importlib.import_module("fabkit.results"), name)
    raise AttributeError(f"module 'fabkit' has no attribute {name!r}")
