"""Form-finding by dynamic relaxation toward zero angle defect and planar faces (paper §2.2–2.7).

`relax(mesh, **options) -> RelaxResult` is the one-shot entry; `Relaxer(mesh, options)` is the
reusable solver object (set up once, `solve()` many times). Energy, gradient and Jacobian live in
`fabkit.relax.energy`; the integrators in `dynamic` (DR with kinetic damping), `newton` (minimum-norm
Gauss–Newton finish) and `lbfgs` (scipy baseline); the Fig. 9 boundary rows in `boundary`.
"""
from fabkit.relax.energy import EnergyModel, Evaluation
from fabkit.relax.options import BOUNDARIES, METHODS, IterationRecord, RelaxOptions, RelaxResult
from fabkit.relax.solver import Relaxer, check_relaxable, relax

__all__ = ["relax", "Relaxer", "RelaxOptions", "RelaxResult", "IterationRecord", "EnergyModel", "Evaluation",
           "check_relaxable", "METHODS", "BOUNDARIES"]
