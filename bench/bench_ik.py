"""IK wrapper throughput against the raw ur_analytic_ik call (the baseline, same run, same poses).

Rows: generic random poses and the degenerate family (wrist 2 at +-90 deg, wrist 3 at 0/180 deg),
for UR5e and UR10e. `ratio` = wrapper time / raw time per call; `recovered` = share of poses whose
generating configuration is among the returned solutions (the raw library misses the degenerate ones).
"""
from __future__ import annotations

import time

import numpy as np

from bench.common import report


def _poses(model, n, degenerate, rng):
    from robot import kinematics as K

    Q = rng.uniform(-np.pi, np.pi, (n, 6))
    if degenerate:
        Q[:, 4] = rng.choice([-np.pi / 2, np.pi / 2], n)
        Q[:, 5] = rng.choice([0.0, np.pi], n)
    return Q, K.fk(model, Q)


def _time_per_call(fn, Ts, repeat=3) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for T in Ts:
            fn(T)
        best = min(best, time.perf_counter() - t0)
    return best / len(Ts)


def main(n: int = 1000) -> dict:
    import ur_analytic_ik

    from robot import kinematics as K

    rng = np.random.default_rng(7)
    rows = []
    for name in ("ur5e", "ur10e"):
        lib = getattr(ur_analytic_ik, name)
        for degenerate in (False, True):
            Q, Ts = _poses(name, n, degenerate, rng)
            Ts = [np.ascontiguousarray(T) for T in Ts]
            with K.quiet_stdout():  # the raw call prints warnings on the degenerate poses
                t_raw = _time_per_call(lib.inverse_kinematics, Ts)
                raw_found = np.mean([len(s) > 0 and K.wrapped_distance(np.array(s), q).min() < 1e-8
                                     for s, q in zip((lib.inverse_kinematics(T) for T in Ts), Q)])
            t_wrap = _time_per_call(lambda T: K.ik(name, T), Ts)
            found = np.mean([K.wrapped_distance(K.ik(name, T), q).min() < 1e-8 for T, q in zip(Ts, Q)])
            rows.append({"model": name, "poses": "degenerate" if degenerate else "generic", "n": n,
                         "raw_us": t_raw * 1e6, "wrapper_us": t_wrap * 1e6, "ratio": t_wrap / t_raw,
                         "raw_recovered": float(raw_found), "recovered": float(found)})
    return report("bench_ik", rows, meta={"what": "ik() (FK-verified, degenerate recovery, stdout contained) "
                                                  "vs raw ur_analytic_ik.inverse_kinematics, per call"})


if __name__ == "__main__":
    main()
