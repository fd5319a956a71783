"""One self-contained HTML page for a demo or any other run folder: numbers, plots, renders, links.

No network: every picture is embedded as a base64 data URI, the CSS is inline, and the plots are
drawn here with matplotlib (Agg) from the stages' own JSON reports and output files.
"""
from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from fabkit.io.atomic import atomic_write

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2rem auto;max-width:1100px;
color:#1d232a;padding:0 1rem}
h1{font-size:1.6rem;margin-bottom:.2rem} h2{font-size:1.2rem;margin-top:2rem;border-bottom:1px solid #ddd}
table{border-collapse:collapse;width:100%;font-size:.9rem} th,td{padding:.35rem .5rem;border-bottom:1px solid #eee;
text-align:left;vertical-align:top} th{background:#f5f7f9}
.pass{color:#0a7a2f;font-weight:600}.fail,.error{color:#b3261e;font-weight:600}.skipped{color:#9a6700}
figure{display:inline-block;margin:.5rem;vertical-align:top;max-width:520px} figure img{max-width:100%;
border:1px solid #ddd} figcaption{font-size:.8rem;color:#555}
code{background:#f2f2f2;padding:0 .25rem;border-radius:3px} .muted{color:#666;font-size:.85rem}
"""


def _png_data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _figure_png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return buf.getvalue()


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _series(history: Any, *names: str) -> list[float] | None:
    """A history given as a list of dicts or a dict of lists -> the first named series present."""
    if isinstance(history, dict):
        for n in names:
            if isinstance(history.get(n), list):
                return [np.nan if v is None else float(v) for v in history[n]]
    if isinstance(history, list) and history and isinstance(history[0], dict):
        for n in names:
            if n in history[0]:
                return [np.nan if h.get(n) is None else float(h.get(n)) for h in history]
    return None


def plot_relax_history(report: dict) -> bytes | None:
    """Max |angle defect| and max planarity per iteration (log scale)."""
    hist = report.get("history")
    defect = _series(hist, "max_defect", "max_abs_angle_defect_rad", "max_abs_defect")
    planar = _series(hist, "max_planarity")
    if not defect and not planar:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 3.2))
    if defect:
        ax.semilogy(np.maximum(defect, 1e-18), label="max |angle defect| [rad]")
    if planar:
        ax.semilogy(np.maximum(planar, 1e-18), label="max planarity")
    ax.set_xlabel("iteration")
    ax.grid(True, which="both", alpha=.3)
    ax.legend()
    ax.set_title("relaxation history")
    return _figure_png(fig)


def plot_joints(path_json: dict, check: dict | None = None) -> bytes | None:
    """Joint angles per waypoint and, from the check, the fastest joint against its speed limit."""
    wps = path_json.get("waypoints") or []
    if not wps:
        return None
    q = np.array([w["q"] for w in wps], dtype=float)
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(5.5, 5), sharex=True)
    for j in range(q.shape[1]):
        a1.plot(np.degrees(q[:, j]), label=f"q{j + 1}")
    a1.set_ylabel("joint angle [deg]")
    a1.legend(ncol=6, fontsize=7)
    a1.grid(alpha=.3)
    a1.set_title("joint trajectory")
    ratio = ((check or {}).get("along_path") or {}).get("joint_speed_ratio")
    if isinstance(ratio, list) and ratio:
        r = np.array([np.nan if v is None else float(v) for v in ratio])
        a2.plot(np.arange(len(r)), 100 * r, label="fastest joint / its limit")
        a2.axhline(100, color="r", ls="--", label="limit")
        a2.set_ylabel("joint speed [% of limit]")
        a2.set_ylim(0, max(110, float(np.nanmax(100 * r)) * 1.1 if np.isfinite(r).any() else 110))
    else:
        dq = np.degrees(np.abs(np.diff(q, axis=0))).max(axis=1)
        a2.plot(range(1, len(q)), dq, label="max |Δq| per segment")
        a2.set_ylabel("max joint change [deg]")
    a2.legend(fontsize=7)
    a2.set_xlabel("waypoint")
    a2.grid(alpha=.3)
    return _figure_png(fig)


def plot_clearance(check: dict) -> bytes | None:
    """Closest obstacle/panel distance per waypoint; points beyond the measuring window are omitted."""
    along = check.get("along_path") or {}
    series = along.get("clearance_m")
    if not isinstance(series, list) or not series:
        return None
    x = np.asarray(along.get("waypoint", range(len(series))))
    y = np.array([np.nan if v is None else 1000 * float(v) for v in series])
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 3))
    ax.plot(x, y, "o-", ms=3, label="closest obstacle or panel face")
    lim = check.get("clearance_limit_m")
    if lim is not None:
        ax.axhline(1000 * float(lim), color="r", ls="--", label="clearance limit")
    window = check.get("clearance_window_m")
    if window:
        ax.axhline(1000 * float(window), color="grey", ls=":", label="measuring window (none closer: no point)")
    if not np.isfinite(y).any() and window:
        ax.text(0.5, 0.5, f"nothing came within {1000 * float(window):.0f} mm of the robot\nat any waypoint",
                ha="center", va="center", transform=ax.transAxes)
        ax.set_ylim(0, 1200 * float(window))
    ax.set_xlabel("waypoint")
    ax.set_ylabel("clearance [mm]")
    ax.grid(alpha=.3)
    ax.legend(fontsize=7)
    ax.set_title("clearance along the path")
    return _figure_png(fig)


def _img(src_png: bytes | None, caption: str) -> str:
    if not src_png:
        return ""
    return (f'<figure><img alt="{html.escape(caption)}" src="{_png_data_uri(src_png)}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def _numbers_table(report: dict, limit: int = 40) -> str:
    """Scalar entries of a report, flattened one level, as a small table."""
    rows = []
    for k, v in report.items():
        if isinstance(v, (int, float, str, bool)) and not isinstance(v, str) or (isinstance(v, str) and len(v) < 120):
            rows.append((k, v))
        elif isinstance(v, dict):
            for k2, v2 in v.items():
                if isinstance(v2, (int, float, bool)) or (isinstance(v2, str) and len(v2) < 120):
                    rows.append((f"{k}.{k2}", v2))
        if len(rows) >= limit:
            break
    if not rows:
        return ""
    fmt = lambda v: f"{v:.6g}" if isinstance(v, float) else str(v)  # noqa: E731
    body = "".join(f"<tr><td><code>{html.escape(k)}</code></td><td>{html.escape(fmt(v))}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def write_report_html(out: Path, summary: dict) -> Path:
    """Write `out/report.html` for a run summarised by `summary` (`fabkit.demo/1`, or the
    `fabkit.run/1` summary `fabkit.report.run.summarize_run` makes for any run folder)."""
    out = Path(out)
    stages = summary.get("stages", [])
    parts = [f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>fabkit report</title>"
             f"<style>{CSS}</style></head><body>",
             "<h1>fabkit pipeline report</h1>",
             f"<p class='muted'>output folder <code>{html.escape(str(out))}</code>, total "
             f"{summary.get('total_seconds', 0):.1f} s</p>",
             "<h2>Stages</h2><table><tr><th>stage</th><th>result</th><th>measure</th><th>tolerance</th>"
             "<th>time</th><th>note</th></tr>"]
    for s in stages:
        parts.append(f"<tr><td>{html.escape(s['name'])}</td><td class='{s['status']}'>{s['status']}</td>"
                     f"<td>{html.escape(s.get('measure') or '')}</td><td>{html.escape(s.get('tolerance') or '')}</td>"
                     f"<td>{s.get('seconds', 0):.2f} s</td><td>{html.escape(s.get('message') or '')}</td></tr>")
    parts.append("</table>")

    def first(kind: str) -> dict:
        return next((s for s in stages if s["name"].split(" ")[0] == kind), {})

    figures = []
    relax = first("relax").get("report") or {}
    figures.append(_img(plot_relax_history(relax), "max angle defect and planarity per iteration"))
    captions = {"unfold_error.png": "flat pattern coloured by relative edge-length deviation",
                "fold_angles.png": "fold angle per crease vs fold state", "check.png": "MuJoCo cell at a waypoint"}
    known = [out / n for n in captions]
    others = sorted(f for f in out.glob("*.png") if f not in known)
    for f in known + others:  # the demo's pictures first, then every other picture in the folder
        if f.exists():
            figures.append(_img(f.read_bytes(), captions.get(f.name, f.name)))
    toolpath_out = (first("toolpath").get("report") or {}).get("output")
    path_json = _read_json(out / Path(toolpath_out).name) if toolpath_out else _read_json(out / "path.json")
    check_json = first("check").get("report") or {}
    if "along_path" not in check_json:  # a stage summary without the per-waypoint numbers: the file has them
        check_json = _read_json(out / "check.json") or check_json
    figures.append(_img(plot_joints(path_json, check_json), "joint angles and speeds along the toolpath"))
    figures.append(_img(plot_clearance(check_json), "clearance along the path"))
    figures = [f for f in figures if f]
    parts.append("<h2>Plots and renders</h2>")
    parts.append("".join(figures) if figures else "<p class='muted'>no plots yet</p>")
    if (out / "check.mp4").exists():  # a local file next to the page: no network
        parts.append("<figure><video controls muted loop width='520' src='check.mp4'></video>"
                     "<figcaption>the whole program in the MuJoCo cell (check.mp4)</figcaption></figure>")

    from fabkit.report.sheet import sheet_section

    toolpath_doc = first("toolpath").get("report") or {}
    parts.append(sheet_section(path_json or (toolpath_doc if "waypoints" in toolpath_doc else {}), check_json))
    from fabkit.report.holds import holds_section

    parts.append(holds_section(check_json if "holds" in check_json else _read_json(out / "check.json")))
    parts.append("<h2>Numbers per stage</h2>")
    for s in stages:
        table = _numbers_table(s.get("report") or {})
        if table:
            parts.append(f"<h3>{html.escape(s['name'])}</h3>{table}")

    parts.append("<h2>Artifacts</h2><ul>")
    for f in sorted(out.iterdir()):
        if f.is_file() and f.name != "report.html" and not f.name.startswith("."):
            parts.append(f"<li><a href='{html.escape(f.name)}'>{html.escape(f.name)}</a> "
                         f"<span class='muted'>({f.stat().st_size / 1024:.1f} kB)</span></li>")
    parts.append("</ul></body></html>")
    target = out / "report.html"
    with atomic_write(target) as fh:
        fh.write("\n".join(parts))
    return target
