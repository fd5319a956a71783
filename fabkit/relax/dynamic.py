"""Dynamic relaxation with lumped masses and kinetic damping (paper §2.2, §2.6; Barnes 1999).

Leapfrog: v ← (1 − c) v + Δt F/m, x ← x + Δt v with Δt = 1 and lumped masses m from a Gershgorin
bound of the Gauss–Newton stiffness JᵀJ (m_i = ½ Σ_j |JᵀJ|_ij, which keeps Δt² λ_max(M⁻¹K) ≤ 2 < 4,
the leapfrog stability limit). Kinetic damping: when the kinetic energy drops (a peak has passed),
velocities are reset to zero at the better of the last two positions (masses are refreshed at a reset
at most every `mass_every` iterations; measured: refreshing at every reset is the robust choice on the
tri-fold boundary rows, rarer refreshes saved time but stalled one of them).
Guard rails: a non-finite or exploding energy reverts the step and doubles the masses (halves the
effective step); too many of those in a row ends the run as "diverged".

Hand-written: scipy has no dynamic-relaxation integrator.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from fabkit.relax.energy import EnergyModel, Evaluation


@dataclass
class PhaseOutcome:
    X: np.ndarray
    evaluation: Evaluation
    iterations: int
    status: str   # "converged" | "switch" | "stalled" | "max_iter" | "diverged" | "timeout"


def lumped_masses(model: EnergyModel, X: np.ndarray, planarity_weight: float | None = None) -> np.ndarray:
    """Per-vertex masses (n,) from a Gershgorin bound of JᵀJ (+ closeness), Δt = 1."""
    _, J = model.residuals_and_jacobian(X, planarity_weight=planarity_weight)
    A = abs(J)
    s = A.T @ (A @ np.ones(A.shape[1]))          # row sums of |J|ᵀ|J| per free coordinate
    s = s.reshape(-1, 3).max(axis=1) + model.w_c / model.L ** 2
    m = np.ones(model.n)
    positive = s[s > 0]
    floor = positive.max() * 1e-6 if len(positive) else 1.0
    m[model.free_mask] = 0.5 * np.maximum(s, floor)
    return m


def dynamic_relaxation(model: EnergyModel, X0: np.ndarray, *, max_iter: int,
                       done: Callable[[Evaluation], bool], switch: Callable[[Evaluation], bool] | None = None,
                       damping: float = 0.0, planarity_weight: float | None = None,
                       record: Callable[[str, Evaluation, float], None] | None = None, phase: str = "dr",
                       deadline: float | None = None, stall_window: int = 150, stall_ratio: float = 0.9,
                       max_reductions: int = 30, mass_every: int = 1) -> PhaseOutcome:
    """Relax from X0 until `done` (converged) or `switch` (hand over) holds, or progress stalls."""
    X = np.array(X0, dtype=np.float64, copy=True)
    ev = model.evaluate(X, planarity_weight=planarity_weight)
    if not ev.finite:
        return PhaseOutcome(X, ev, 0, "diverged")
    if done(ev):
        return PhaseOutcome(X, ev, 0, "converged")
    free = model.free_mask[:, None]
    m = lumped_masses(model, X, planarity_weight)[:, None]
    mass_it = 0
    scale = 1.0           # step reduction factor applied to the masses after a blow-up
    v = np.where(free, -0.5 * ev.gradient / (m * scale), 0.0)
    ke_prev = 0.0
    e_start = ev.energy
    window_e = ev.energy
    reductions = 0
    status = "max_iter"
    it = 0
    for it in range(1, max_iter + 1):
        X_new = X + v
        ev_new = model.evaluate(X_new, planarity_weight=planarity_weight)
        if not ev_new.finite or ev_new.energy > 1e3 * max(e_start, 1e-300):
            reductions += 1
            if reductions > max_reductions:
                status = "diverged"
                break
            scale *= 2.0
            v = np.where(free, -0.5 * ev.gradient / (m * scale), 0.0)
            ke_prev = 0.0
            continue
        v_next = (1.0 - damping) * v - np.where(free, ev_new.gradient / (m * scale), 0.0)
        ke = 0.5 * float(np.sum(m * scale * v_next * v_next))
        if ke < ke_prev:
            # kinetic-energy peak passed: restart from rest at the better of the last two positions
            if ev_new.energy < ev.energy:
                X, ev = X_new, ev_new
            if it - mass_it >= mass_every:
                m = lumped_masses(model, X, planarity_weight)[:, None]
                mass_it = it
            v = np.where(free, -0.5 * ev.gradient / (m * scale), 0.0)
            ke_prev = 0.0
            reductions = 0
        else:
            X, ev = X_new, ev_new
            v = v_next
            ke_prev = ke
        if record is not None:
            record(phase, ev, ke)
        if done(ev):
            status = "converged"
            break
        if switch is not None and switch(ev):
            status = "switch"
            break
        if it % stall_window == 0:
            if ev.energy > stall_ratio * window_e:
                status = "stalled"
                break
            window_e = ev.energy
        if deadline is not None and time.perf_counter() > deadline:
            status = "timeout"
            break
    return PhaseOutcome(X, ev, it, status)
