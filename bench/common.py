"""Helpers for benchmarks: timing, a printed table and JSON output in bench/results/."""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Callable

RESULTS = Path(__file__).parent / "results"


def best_time(fn: Callable[[], object], repeat: int = 3) -> float:
    """Best wall time of `repeat` runs, in seconds."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def report(name: str, rows: list[dict], meta: dict | None = None) -> dict:
    """Print `rows` as a table and write {"name", "meta", "rows"} to bench/results/<name>.json."""
    RESULTS.mkdir(exist_ok=True)
    cols = list(dict.fromkeys(k for r in rows for k in r))
    fmt = lambda v: f"{v:.4g}" if isinstance(v, float) else str(v)  # noqa: E731
    widths = [max(len(c), *(len(fmt(r.get(c, ""))) for r in rows)) for c in cols]
    print("  ".join(c.ljust(w) for c, w in zip(cols, widths)))
    for r in rows:
        print("  ".join(fmt(r.get(c, "")).ljust(w) for c, w in zip(cols, widths)))
    data = {"name": name, "meta": meta or {}, "rows": rows}
    (RESULTS / f"{name}.json").write_text(json.dumps(data, indent=1))
    return data
