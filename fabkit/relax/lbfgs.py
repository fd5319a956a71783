"""scipy L-BFGS-B on the relaxation energy (the quasi-Newton baseline the benchmark compares with DR)."""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from fabkit.relax.dynamic import PhaseOutcome
from fabkit.relax.energy import EnergyModel, Evaluation


def lbfgs(model: EnergyModel, X0: np.ndarray, *, max_iter: int, done: Callable[[Evaluation], bool],
          switch: Callable[[Evaluation], bool] | None = None,
          record: Callable[[str, Evaluation, float], None] | None = None,
          deadline: float | None = None, memory: int = 20) -> PhaseOutcome:
    """Minimise E over the free coordinates with scipy's L-BFGS-B until `done` / `switch` holds."""
    from scipy.optimize import minimize  # on use: scipy.optimize costs ~0.4 s to import

    X0 = np.array(X0, dtype=np.float64, copy=True)
    ev0 = model.evaluate(X0)
    if not ev0.finite:
        return PhaseOutcome(X0, ev0, 0, "diverged")
    if done(ev0):
        return PhaseOutcome(X0, ev0, 0, "converged")
    cache: dict = {"y": None, "ev": ev0, "best": (ev0.energy, X0, ev0)}
    state = {"status": "max_iter", "it": 0}

    def fun(y):
        X = model.unpack(y, X0)
        ev = model.evaluate(X)
        cache["y"], cache["ev"] = y.copy(), ev
        if not ev.finite:
            return np.inf, np.zeros_like(y)
        if ev.energy < cache["best"][0]:
            cache["best"] = (ev.energy, X, ev)
        return ev.energy, model.pack(ev.gradient)

    def callback(intermediate_result):
        state["it"] += 1
        y = intermediate_result.x
        ev = cache["ev"] if cache["y"] is not None and np.array_equal(cache["y"], y) else \
            model.evaluate(model.unpack(y, X0))
        if record is not None:
            record("lbfgs", ev, 0.0)
        if done(ev):
            state["status"] = "converged"
            raise StopIteration
        if switch is not None and switch(ev):
            state["status"] = "switch"
            raise StopIteration
        if deadline is not None and time.perf_counter() > deadline:
            state["status"] = "timeout"
            raise StopIteration

    res = minimize(fun, model.pack(X0), jac=True, method="L-BFGS-B", callback=callback,
                   options={"maxiter": max(int(max_iter), 1), "maxcor": memory, "ftol": 0.0, "gtol": 0.0,
                            "maxfun": 20 * max(int(max_iter), 1) + 100})
    X = model.unpack(res.x, X0)
    ev = model.evaluate(X)
    if not ev.finite or ev.energy > cache["best"][0]:
        _, X, ev = cache["best"]
    status = state["status"]
    if status == "max_iter" and state["it"] < max_iter:
        status = "stalled"  # line search could not make progress
    return PhaseOutcome(X, ev, state["it"], status)
