"""Form-finding by dynamic relaxation toward zero angle defect and planar faces (paper §2.2–2.7).

`relax(mesh, **options) -> RelaxResult` is the one-shot entry; `Relaxer(mesh, options)` is the
reusable solver object (set up once, `solve()` many times). Energy, gradient and Jacobian live in
`fabkit.relax.energy`; the integrators in `dynamic` (DR with kinetic damping), `newton` (minimum-norm
Gauss–Newton finish) and `lbfgs` (scipy baseline); the Fig. 9 boundary rows in `boundary`.
"""
import importlib

#: public name -> the module that defines it. Imported on first use (PEP 562), so that
#: `fabkit.relax.options` (the CLI's defaults) loads without the solvers and scipy.
_HOME = {
    "relax": "solver", "Relaxer": "solver", "check_relaxable": "solver",
    "RelaxOptions": "options", "RelaxResult": "options", "IterationRecord": "options",
    "METHODS": "options", "BOUNDARIES": "options",
    "EnergyModel": "energy", "Evaluation": "energy",
}
__all__ = list(_HOME)


def __getattr__(name: str):
    if name not in _HOME:
        raise AttributeError(f"module 'fabkit.relax' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"fabkit.relax.{_HOME[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
