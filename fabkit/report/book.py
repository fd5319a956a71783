"""The production book: one self-contained HTML page for a production run.

The surface coloured by panel status, robot cycle time and unfold error; a sortable table of the
panels (built in the page from the embedded JSON, click a header to sort) with links to each
panel's cut file, FOLD files, program, check and 3D model; the nesting sheets as pictures; totals;
the assembly order with every panel's neighbours and face up. No network: pictures are base64 data
URIs, CSS and script are inline (the patterns of `fabkit.report.html`).
"""
from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path

import numpy as np

from fabkit.io.atomic import atomic_write, written_path
from fabkit.io.jsonfile import to_jsonable, write_json
from fabkit.report.html import CSS

__all__ = ["write_book", "book_html"]

STATUS_COLOURS = {"ok": "#2e9d4f", "relax": "#7b3294", "unfold": "#c2a5cf", "refold": "#e66101",
                  "program": "#fdb863", "check": "#d7191c"}

SCRIPT = """
const data = JSON.parse(document.getElementById('panel-data').textContent);
const cols = [['name','panel'],['band','band'],['status','status'],['reason','reason'],['same_as','same part as'],['cycle_time_s','cycle s'],
  ['unfold_max','unfold max'],['sheet','sheet'],['links','files']];
const kinds = [['dxf','cut'],['refold','FOLD'],['crease_pattern','pattern'],['program','program'],['check','check'],
  ['obj','3D']];
let sortKey = 'name', sortDir = 1;
function cell(p, k) {
  if (k === 'links') return kinds.filter(([f]) => p.files[f]).map(([f, l]) => `<a href="${p.files[f]}">${l}</a>`).join(' ');
  const v = p[k];
  if (v === null || v === undefined) return '—';
  if (typeof v === 'number' && !Number.isInteger(v)) return k === 'unfold_max' ? v.toExponential(2) : v.toFixed(1);
  return String(v).replace(/[&<>]/g, c => ({'&':'&amp;','<':'&lt;','>':'&gt;'}[c]));
}
function render() {
  const rows = data.slice().sort((a, b) => {
    const x = a[sortKey], y = b[sortKey];
    if (x === y) return 0;
    if (x === null || x === undefined) return 1;
    if (y === null || y === undefined) return -1;
    return (x < y ? -1 : 1) * sortDir;
  });
  const head = '<tr>' + cols.map(([k, l]) => `<th data-key="${k}">${l}${k === sortKey ? (sortDir > 0 ? ' ▲' : ' ▼') : ''}</th>`).join('') + '</tr>';
  const body = rows.map(p => `<tr class="${p.ok ? 'row-ok' : 'row-fail'}" data-panel="${p.name}">` +
    cols.map(([k]) => `<td class="${k === 'status' ? (p.ok ? 'pass' : 'fail') : ''}">${cell(p, k)}</td>`).join('') + '</tr>').join('');
  document.getElementById('panels').innerHTML = '<thead>' + head + '</thead><tbody>' + body + '</tbody>';
  document.querySelectorAll('#panels th').forEach(th => th.onclick = () => {
    const k = th.dataset.key; if (k === 'links') return;
    sortDir = (k === sortKey) ? -sortDir : 1; sortKey = k; render();
  });
}
render();
"""


def _png_uri(fig) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _surface_figures(run, report) -> list[tuple[str, str]]:
    """(caption, data URI): the relaxed panels' outlines in 3D coloured by status, cycle time, unfold error."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm, colors
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    layout = run.geometry.layout
    polys = []
    for p, r in zip(layout.panels, run.geometry.results):
        loop = max(p.mesh.boundary_loops, key=len)
        polys.append(np.asarray(r.relaxed)[loop])
    allp = np.vstack(polys)
    per = report["panels"]
    out = []
    cycle = np.array([np.nan if q["cycle_time_s"] is None else q["cycle_time_s"] for q in per], float)
    unfold = np.array([q["unfold_max"] for q in per], float)
    for caption, values, kind in (("panel status", [q["status"] for q in per], "status"),
                                  ("robot cycle time [s] (grey: no program)", cycle, "cycle"),
                                  ("max unfold deviation (relative, log10)", np.log10(np.maximum(unfold, 1e-16)), "unfold")):
        fig = plt.figure(figsize=(6.5, 4.2))
        ax = fig.add_subplot(111, projection="3d")
        if kind == "status":
            fc = [STATUS_COLOURS.get(v, "#888888") for v in values]
        else:
            v = np.asarray(values, float)
            fin = np.isfinite(v)
            norm = colors.Normalize(*(np.nanmin(v[fin]), np.nanmax(v[fin])) if fin.any() else (0, 1))
            fc = [cm.viridis(norm(x)) if np.isfinite(x) else "#bbbbbb" for x in v]
            fig.colorbar(cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax, shrink=0.6)
        ax.add_collection3d(Poly3DCollection(polys, facecolors=fc, edgecolors="k", linewidths=0.2),
                          autolim=False)  # the limits are set below; matplotlib 3.11 autoscaling overflowed
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(np.maximum(hi - lo, 1e-3))
        ax.set_axis_off()
        if kind == "status":
            seen = sorted(set(values))
            ax.legend(handles=[plt.Rectangle((0, 0), 1, 1, color=STATUS_COLOURS.get(s, "#888")) for s in seen],
                      labels=seen, loc="upper left", fontsize=7)
        out.append((caption, _png_uri(fig)))
    return out


def book_html(run, report: dict, out: Path) -> str:
    """The page (see the module docstring); `out` is the run folder (sheet pictures are read from it)."""
    e = html.escape
    t = report["totals"]
    figs = _surface_figures(run, report)
    sheets = []
    for s in report.get("sheets", []):
        png = written_path(out / s["png"]) if s.get("png") else None  # staged until the run commits
        uri = ("data:image/png;base64," + base64.b64encode(png.read_bytes()).decode("ascii")) if png and png.is_file() else ""
        sheets.append(f'<figure><img alt="sheet {s["sheet"]}" src="{uri}"><figcaption>sheet {s["sheet"]}: '
                      f'{len(s["panels"])} panels, {s["utilisation"]:.0%} of the sheet; <a href="{e(s["dxf"])}">DXF</a> '
                      f'<a href="{e(s["svg"])}">SVG</a></figcaption></figure>')
    fail_rows = "".join(f"<tr><td>failed at {e(k)}</td><td>{v}</td></tr>" for k, v in sorted(t["failed_by_stage"].items()))
    asm = report["assembly"]["panels"]
    asm_rows = "".join(
        f"<tr><td>{a['step']}</td><td>{e(a['id'])}</td><td>{e(', '.join(a['joins']) or '—')}</td>"
        f"<td>{e('; '.join(n['id'] + ' (' + ', '.join(n['sides']) + ')' for n in a['neighbours']))}</td>"
        f"<td>{e(a['face_up'])}</td></tr>" for a in asm)
    panel_data = json.dumps(to_jsonable(report["panels"])).replace("</", "<\\/")
    mat = report["material"]
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>fabkit production book</title>
<style>{CSS} #panels th{{cursor:pointer}} .row-fail td{{background:#fff4f2}}</style></head>
<body>
<h1>Production book</h1>
<p class="muted">{e(str(report["input"].get("surface", "")))} · cell {e(str(report["input"].get("cell", "")))} ·
material {e(mat["name"])} ({mat["thickness_m"] * 1e3:g} mm)</p>
<h2>Totals</h2>
<table id="totals">
<tr><th>panels</th><td>{t["panels"]}</td></tr>
<tr><th>ok</th><td class="pass">{t["ok"]}</td></tr>
<tr><th>failed</th><td class="{'fail' if t['failed'] else ''}">{t["failed"]}</td></tr>
{fail_rows}
<tr><th>robot time</th><td>{t["robot_time_s"] / 60:.1f} min (sum of the cycle times of the panels that passed every stage)</td></tr>
<tr><th>sheets</th><td>{t["sheets"]} × {t["sheet_mm"][0]:g} × {t["sheet_mm"][1]:g} mm</td></tr>
<tr><th>nesting utilisation</th><td>{t["utilisation"]:.1%} (every sheet whole); {t["utilisation_last_sheet_by_length"]:.1%}
(last sheet by used length)</td></tr>
<tr><th>material</th><td>{t["material_area_m2"]:.2f} m² of sheet, {t["material_kg"]:.1f} kg; panels {t["panel_area_m2"]:.2f} m²,
{t["panel_mass_kg"]:.1f} kg</td></tr>
</table>
<h2>Surface</h2>
{''.join(f'<figure><img alt="{e(c)}" src="{u}"><figcaption>{e(c)}</figcaption></figure>' for c, u in figs)}
<h2>Panels</h2>
<p class="muted">Click a column header to sort. Files are relative to this page.</p>
<table id="panels"></table>
<script type="application/json" id="panel-data">{panel_data}</script>
<h2>Nesting</h2>
<p class="muted">{e(report["nesting"]["engine"])}, gap {report["nesting"]["spacing_mm"]:g} mm + kerf
{report["nesting"]["kerf_mm"]:g} mm, {report["nesting"].get("edge_mm", report["nesting"]["spacing_mm"]):g} mm to the
sheet edge, grain {e(report["nesting"]["grain"])}; {e('; '.join(report["nesting"]["notes"]))}</p>
{''.join(sheets)}
<h2>Assembly</h2>
<p class="muted">Also in <a href="assembly.json">assembly.json</a>.</p>
<table id="assembly"><tr><th>step</th><th>panel</th><th>joins</th><th>neighbours (sides)</th><th>face up</th></tr>
{asm_rows}</table>
<script>{SCRIPT}</script>
</body></html>
"""


def write_book(run, nest, report: dict, out: str | Path) -> Path:
    """Write `out/book.html` and `out/assembly.json`; returns the page's path."""
    out = Path(out)
    write_json(out / "assembly.json", report["assembly"])
    page = out / "book.html"
    with atomic_write(page) as fh:
        fh.write(book_html(run, report, out))
    return page
