"""fabkit: curved-crease folded panels from coarse mesh to robot fold program.

Geometry layer (this package): mesh core, procedural generation, relaxation, development,
refolding, face frames, file formats and the `fabkit` CLI. Units: metres and radians inside.
"""
from fabkit.errors import FabkitError, InputError, ToleranceError

__version__ = "0.1.0"
__all__ = ["FabkitError", "InputError", "ToleranceError", "__version__"]
