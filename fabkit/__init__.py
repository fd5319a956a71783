"""fabkit: curved-crease folded panels from coarse mesh to robot fold program.

The public API is the pipeline, one typed function per stage (`fabkit.pipeline`, docs/api.md):
`load` / `generate` -> `relax` -> `unfold` -> `refold` -> `plan` -> `check` -> `send`, each
returning a frozen result (`fabkit.results`) with `ok`, `problems` and `to_json()`. Units: metres
and radians inside. `import fabkit` loads no numpy, robot or sim code; the stages import what
they need when called.

The stage names `generate`, `relax`, `unfold` and `refold` are also subpackages (the geometry
layer). On `fabkit` they are the stage functions and stay so: importing a subpackage does not
rebind them (`_Package.__setattr__`). Import the subpackages by their full name:
`from fabkit.relax import Relaxer`, `importlib.import_module("fabkit.unfold")`.
"""
import sys
import types

from fabkit.errors import FabkitError, InputError, ToleranceError
from fabkit.pipeline import check, generate, load, plan, refold, relax, send, unfold
from fabkit.results import Checked, Flat, Folds, Panel, Program, Relaxed, Sent

__version__ = "0.1.0"
__all__ = ["load", "generate", "relax", "unfold", "refold", "plan", "check", "send",
           "Panel", "Relaxed", "Flat", "Folds", "Program", "Checked", "Sent",
           "FabkitError", "InputError", "ToleranceError", "__version__"]

#: names that are both a stage function and a subpackage
_STAGES = frozenset({"generate", "relax", "unfold", "refold"})


class _Package(types.ModuleType):
    """The `fabkit` module: importing the subpackage `fabkit.relax` (which makes Python set the
    attribute `fabkit.relax` to it) leaves the stage function `fabkit.relax` in place; the
    subpackage is in `sys.modules` under its full name."""

    def __setattr__(self, name, value):
        if name in _STAGES and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
