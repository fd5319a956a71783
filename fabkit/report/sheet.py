"""The sheet section of report.html: per fold state the design and programmed (overbent) angle of
every crease, from PATH.json's `sheet` record, and the fold-load verdicts per state, from
CHECK.json's `loads` (else from the verdicts PATH.json recorded at planning, said so)."""
from __future__ import annotations

import html

__all__ = ["sheet_section"]


def _e(x) -> str:
    return html.escape(str(x))


def _angles_table(sheet: dict) -> str:
    rows = []
    for st in sheet.get("states") or []:
        for c in st.get("creases") or []:
            d, p = c.get("design_deg"), c.get("programmed_deg")
            if not isinstance(d, (int, float)) or not isinstance(p, (int, float)):
                continue
            rows.append(f"<tr><td>{_e(st.get('state'))}</td><td>{_e(c.get('crease'))}</td><td>{d:.2f}</td>"
                        f"<td>{p:.2f}</td><td>{p - d:+.2f}</td><td>{c.get('max_overbend_deg', 0):.2f}</td></tr>")
    if not rows:
        return ""
    return ("<table id='sheet-angles'><tr><th>state</th><th>crease</th><th>design angle [deg]</th>"
            "<th>programmed angle [deg]</th><th>overbend (mean) [deg]</th><th>largest overbend [deg]</th></tr>"
            + "".join(rows) + "</table>")


def _check_rows(loads: dict) -> list[tuple]:
    """(state, crease, check, moment, demand, capacity, unit, ratio, ok, remedy) from CHECK.json's
    per-state records or PATH.json's flat verdict list."""
    out = []
    if isinstance(loads.get("states"), list):
        for st in loads["states"]:
            for c in st.get("checks") or []:
                out.append((st.get("state"), c.get("crease"), c.get("check"), c.get("moment_nm"), c.get("demand"),
                            c.get("capacity"), c.get("unit"), c.get("ratio"), c.get("ok"), c.get("remedy")))
        return out
    for v in loads.get("verdicts") or []:
        cap = v.get("capacity")
        ratio = v["demand"] / cap if isinstance(cap, (int, float)) and cap > 0 else None
        out.append((v.get("state"), v.get("crease"), v.get("check"), None, v.get("demand"), cap, v.get("unit"),
                    ratio, v.get("ok"), v.get("remedy")))
    return out


def _num(x, fmt: str = ".1f") -> str:
    return format(x, fmt) if isinstance(x, (int, float)) and not isinstance(x, bool) else "—"


def _loads_table(loads: dict) -> str:
    rows = []
    for state, crease, check, moment, demand, cap, unit, ratio, ok, remedy in _check_rows(loads):
        verdict = "pass" if ok else "fail"
        rows.append(f"<tr><td>{_e(state)}</td><td>{_e(crease)}</td><td>{_e(check)}</td><td>{_num(moment)}</td>"
                    f"<td>{_num(demand)} {_e(unit or '')}</td><td>{_num(cap)} {_e(unit or '')}</td>"
                    f"<td>{_num(ratio, '.0%')}</td><td class='{verdict}'>{verdict}</td>"
                    f"<td>{'' if ok else _e(remedy or '')}</td></tr>")
    if not rows:
        return ""
    return ("<table id='sheet-loads'><tr><th>state</th><th>crease</th><th>check</th><th>fold moment [N m]</th>"
            "<th>demand</th><th>capacity</th><th>ratio</th><th>verdict</th><th>remedy</th></tr>"
            + "".join(rows) + "</table>")


def sheet_section(path_json: dict, check_json: dict) -> str:
    """The HTML of the sheet section, or "" when neither file says anything about a sheet."""
    sheet = (path_json or {}).get("sheet")
    loads = (check_json or {}).get("loads")
    source = "the check (CHECK.json)"
    if not isinstance(loads, dict) and isinstance(sheet, dict) and isinstance(sheet.get("loads"), dict):
        loads, source = sheet["loads"], "planning (PATH.json; run fabkit check for the checked verdicts)"
    if not isinstance(sheet, dict) and not isinstance(loads, dict):
        return ""
    parts = ["<h2>Sheet</h2>"]
    spec = sheet if isinstance(sheet, dict) else (loads or {}).get("sheet") or {}
    if spec:
        parts.append(f"<p>{_e(spec.get('thickness_mm', '?'))} mm {_e(spec.get('material', '?'))}, "
                     f"{_e(spec.get('crease', ''))}, inside radius {_e(spec.get('inside_radius_mm', '?'))} mm</p>")
    if isinstance(sheet, dict):
        table = _angles_table(sheet)
        if table:
            parts.append("<h3>Fold angles per state: design and programmed (springback-compensated)</h3>" + table)
        pays = [("", (path_json or {}).get("payload"))] + [  # one arm, or each arm of a two-arm program
            (f"arm {a.get('name')}: ", a.get("payload")) for a in (path_json or {}).get("arms") or []
            if isinstance(a, dict)]
        for who, pay in pays:
            if isinstance(pay, dict):
                held = "its share of the panel" if who else "panel"
                parts.append(f"<p>{_e(who)}payload declared: tool {_num(pay.get('tool_mass_kg'), '.3f')} kg, tool + "
                             f"{held} {_num(pay.get('held_mass_kg'), '.3f')} kg while held (CoG in the flange "
                             "frame)</p>")
    if isinstance(loads, dict):
        table = _loads_table(loads)
        verdict = "pass" if loads.get("ok") else "fail"
        parts.append(f"<h3>Fold loads per state on the {_e(loads.get('arm', '?'))}: <span class='{verdict}'>"
                     f"{verdict}</span></h3><p class='muted'>verdicts from {_e(source)}</p>" + table)
    return "\n".join(parts)
