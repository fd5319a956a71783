"""A report summary for any run folder: the stages' own JSON reports found and read, nothing assumed.

`summarize_run(DIR)` returns the `fabkit.demo/1`-shaped summary `write_report_html` draws: a demo's
`summary.json` as it is, otherwise one stage per JSON report in DIR (relax, unfold, refold,
toolpath, check, panels, info: recognised by their `format` / `command` keys or their fields),
with its status taken from the report's own verdict (`ok`, `converged`, `passed`). Files that are
not fabkit reports are listed as artifacts only.
"""
from __future__ import annotations

import json
from pathlib import Path

__all__ = ["summarize_run", "STAGE_ORDER"]

STAGE_ORDER = ("info", "relax", "unfold", "panels", "refold", "toolpath", "check", "send")


def _kind(name: str, d: dict) -> str | None:
    fmt = str(d.get("format", ""))
    if fmt.startswith("fabkit.") and fmt != "fabkit.demo/1":
        kind = fmt.split(".", 1)[1].split("/", 1)[0]
        return kind if kind in STAGE_ORDER else None
    if d.get("command") in STAGE_ORDER:
        return str(d["command"])
    if "converged" in d and "input_summary" in d:
        return "relax"
    return None


def _status(d: dict) -> str:
    for key in ("ok", "passed", "converged"):
        if isinstance(d.get(key), bool):
            if key == "converged" and d.get("max_move", {}).get("ok") is False:
                return "fail"
            return "pass" if d[key] else "fail"
    return "pass" if not d.get("problems") else "fail"


def _measure(kind: str, d: dict) -> str:
    if kind == "relax":
        final = d.get("final") or {}
        return (f"max defect {final.get('max_abs_angle_defect_rad', float('nan')):.3g} rad, planarity "
                f"{final.get('max_planarity', float('nan')):.3g}")
    if kind == "unfold":
        dev = d.get("development", {})
        return f"max length deviation {dev.get('max_relative_deviation', float('nan')):.3g}"
    if kind == "refold":
        return f"{d.get('states', '?')} states"
    if kind == "toolpath":
        return f"{d.get('waypoints', '?')} waypoints"
    return ""


def summarize_run(directory: str | Path) -> dict:
    """The summary of the run in `directory` (see module docstring)."""
    out = Path(directory)
    summary_file = out / "summary.json"
    if summary_file.is_file():
        try:
            d = json.loads(summary_file.read_text(encoding="utf-8"))
            if isinstance(d, dict) and d.get("format") == "fabkit.demo/1":
                return d
        except (OSError, ValueError):
            pass
    stages = []
    for f in sorted(out.glob("*.json")):
        try:
            d = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if not isinstance(d, dict):
            continue
        kind = _kind(f.name, d)
        if kind is None:
            continue
        problems = d.get("problems") or []
        stages.append({"name": kind if kind not in {s["name"] for s in stages} else f"{kind} ({f.stem})",
                       "status": _status(d), "exit_code": None, "seconds": float(d.get("seconds", 0) or 0),
                       "measure": _measure(kind, d), "tolerance": "", "file": f.name,
                       "message": "; ".join(str(p) for p in problems)[:300], "report": d})
    stages.sort(key=lambda s: (STAGE_ORDER.index(s["name"].split(" ")[0]), s["name"]))
    return {"format": "fabkit.run/1", "out": str(out), "total_seconds": sum(s["seconds"] for s in stages),
            "stages": stages}
