"""The controller's time law along a path: the time-optimal rest-to-rest profile over pieces with
piecewise-constant speed caps and accelerations (`robot.ur_motion` cuts a run into the pieces).

Per piece the arm accelerates at the piece's `a`, cruises at most at its `v` and decelerates; the
speeds on the piece boundaries come from one forward pass (what the arm can reach accelerating)
and one backward pass (what it can still stop from), which is exact for piecewise-constant limits.
`Profile.time_at` and `Profile.state_at` evaluate the profile in closed form. Hand-written: a
trapezoidal profile with boundary speeds is a few lines; time-optimal path parametrisation
libraries (toppra, ruckig) solve a more general problem.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Profile", "time_law"]


@dataclass(frozen=True, eq=False)
class Profile:
    """Time law of one run: `s` (m+1,) piece boundaries along the path parameter, `vb` (m+1,) speed at
    each boundary, per piece (m,): cap `vmax`, acceleration `amax`, peak speed `vp`, times of the
    acceleration / cruise / deceleration phases `ta`, `tc`, `td`; `t` (m+1,) boundary times."""

    s: np.ndarray
    vb: np.ndarray
    vmax: np.ndarray
    amax: np.ndarray
    vp: np.ndarray
    ta: np.ndarray
    tc: np.ndarray
    td: np.ndarray
    t: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def length(self) -> float:
        return float(self.s[-1])

    def _piece(self, x, edges):
        return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(self.vmax) - 1)

    def time_at(self, s) -> np.ndarray:
        """Times (s) at which the run passes path parameters `s`."""
        s = np.clip(np.asarray(s, dtype=np.float64), 0.0, self.length)
        k = self._piece(s, self.s)
        x = s - self.s[k]
        v0, v1, a, vp = self.vb[k], self.vb[k + 1], self.amax[k], self.vp[k]
        da = (vp ** 2 - v0 ** 2) / (2 * a)
        dd = (vp ** 2 - v1 ** 2) / (2 * a)
        L = self.s[k + 1] - self.s[k]
        with np.errstate(invalid="ignore", divide="ignore"):
            t_acc = (np.sqrt(np.maximum(v0 ** 2 + 2 * a * x, 0.0)) - v0) / a
            t_cru = self.ta[k] + (x - da) / np.where(vp > 0, vp, 1.0)
            y = np.maximum(L - x, 0.0)
            t_dec = self.ta[k] + self.tc[k] + self.td[k] - (np.sqrt(np.maximum(v1 ** 2 + 2 * a * y, 0.0)) - v1) / a
        local = np.where(x <= da, t_acc, np.where(x <= L - dd, t_cru, t_dec))
        return self.t[k] + np.where(L > 0, local, 0.0)

    def state_at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Path parameter and its rate at times `t` (clipped to the run)."""
        t = np.clip(np.asarray(t, dtype=np.float64), 0.0, self.duration)
        k = self._piece(t, self.t)
        tau = t - self.t[k]
        v0, v1, a, vp = self.vb[k], self.vb[k + 1], self.amax[k], self.vp[k]
        ta, tc, td = self.ta[k], self.tc[k], self.td[k]
        L = self.s[k + 1] - self.s[k]
        da = (vp ** 2 - v0 ** 2) / (2 * a)
        tr = np.maximum(ta + tc + td - tau, 0.0)
        s_acc, v_acc = v0 * tau + 0.5 * a * tau ** 2, v0 + a * tau
        s_cru, v_cru = da + vp * (tau - ta), vp
        s_dec, v_dec = L - (v1 * tr + 0.5 * a * tr ** 2), v1 + a * tr
        s = np.where(tau <= ta, s_acc, np.where(tau <= ta + tc, s_cru, s_dec))
        sd = np.where(tau <= ta, v_acc, np.where(tau <= ta + tc, v_cru, v_dec))
        return np.clip(self.s[k] + np.clip(s, 0.0, L), 0.0, self.length), np.maximum(sd, 0.0)


def time_law(lengths, vmax, amax, stops=None) -> Profile:
    """Time-optimal rest-to-rest profile over pieces of path length `lengths` with speed caps `vmax`
    and accelerations `amax` (all (m,), in the path parameter's units); `stops` (m+1,) True where
    the arm must also be at rest on a piece boundary (several runs timed as one profile)."""
    L = np.maximum(np.asarray(lengths, dtype=np.float64), 0.0)
    V = np.asarray(vmax, dtype=np.float64)
    A = np.asarray(amax, dtype=np.float64)
    m = len(L)
    if not (np.all(A > 0) and np.all(V >= 0)):
        raise ValueError("speeds must be >= 0 and accelerations > 0")
    cap = np.zeros(m + 1)
    if m > 1:
        cap[1:-1] = np.minimum(V[:-1], V[1:])
    if stops is not None:
        cap[np.asarray(stops, dtype=bool)] = 0.0
    v2 = (cap ** 2).tolist()
    reach = (2 * A * L).tolist()
    for k in range(m):  # forward: what the arm can reach accelerating
        v2[k + 1] = min(v2[k + 1], v2[k] + reach[k])
    for k in range(m - 1, -1, -1):  # backward: what it can still stop from
        v2[k] = min(v2[k], v2[k + 1] + reach[k])
    vb2 = np.asarray(v2)
    vb = np.sqrt(vb2)
    vp = np.minimum(V, np.sqrt(np.maximum(A * L + 0.5 * (vb2[:-1] + vb2[1:]), 0.0)))
    vp = np.maximum(vp, np.maximum(vb[:-1], vb[1:]))  # rounding: never below the boundary speeds
    ta = (vp - vb[:-1]) / A
    td = (vp - vb[1:]) / A
    cruise = L - (2 * vp ** 2 - vb2[:-1] - vb2[1:]) / (2 * A)
    with np.errstate(invalid="ignore", divide="ignore"):
        tc = np.where(vp > 0, np.maximum(cruise, 0.0) / vp, 0.0)
    if np.any((L > 0) & (vp <= 0)):
        raise ValueError("the path cannot be run: a speed cap is zero along it")
    t = np.r_[0.0, np.cumsum(ta + tc + td)]
    return Profile(s=np.r_[0.0, np.cumsum(L)], vb=vb, vmax=V, amax=A, vp=vp, ta=ta, tc=tc, td=td, t=t)
