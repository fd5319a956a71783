"""The holds section of report.html: per crease what folds it, per fold state which faces are held.

From CHECK.json's `holds` record (`fabkit check`): `creases` (per run of moves with one set of
holds, the holds on each side of every crease row's cut, `sim.check_crease_holds`), `states` (the
proof per fold state) and the hold rows (`clamped_faces`, `arms`, `jigs`: any number of arms).
Nothing here is computed from pictures: the page says what the check found.
"""
from __future__ import annotations

import html

__all__ = ["holds_section", "crease_rows", "state_rows"]


def _e(x) -> str:
    return html.escape(str(x))


def _ranges(faces) -> str:
    """"0–15, 32–47" for sorted face ids (runs of three or more as ranges)."""
    out, run = [], []
    for f in list(faces) + [None]:
        if run and (f is None or f != run[-1] + 1):
            out += [f"{run[0]}–{run[-1]}"] if len(run) >= 3 else [str(x) for x in run]
            run = []
        if f is not None:
            run.append(f)
    return ", ".join(out)


def _side(side: dict) -> str:
    span = f"faces {_ranges(side.get('faces') or [])}"
    holds = side.get("holds") or []
    return f"{span}: {', '.join(holds) if holds else 'nothing'}"


def _verdict(c: dict) -> str:
    sides = c.get("sides") or []
    a0, a1 = (c.get("angle_deg") or [0.0, 0.0])[:2]
    if c.get("set"):
        return f"set earlier: locked at {a1:.1f}°"
    free = [s for s in sides if not s.get("holds")]
    if free:
        return f"FREE: {_side(free[0]).split(':')[0]} held by nothing"
    if len(sides) < 2:
        return "not cut by this crease row"
    who = [" + ".join(s["holds"]) for s in sides]
    if abs(a1 - a0) < 0.05:
        return f"held at {a1:.1f}° between {who[0]} and {who[1]}"
    return f"folded {a0:.1f}° → {a1:.1f}° between {' and '.join(who)}"


def crease_rows(holds: dict) -> list[list[str]]:
    """Rows [crease, waypoints, fold states, one side, other side, verdict] of the per-crease table."""
    rows = []
    for run in holds.get("creases") or []:
        w0, w1 = run["waypoints"]
        s0, s1 = run["states"]
        for c in run.get("creases") or []:
            sides = c.get("sides") or []
            rows.append([str(c["crease"]), f"{w0}–{w1}", f"{s0:g}–{s1:g}",
                         _side(sides[0]) if sides else "", " / ".join(_side(s) for s in sides[1:]), _verdict(c)])
    return rows


def _hold_columns(holds: dict) -> list[tuple[str, str, str]]:
    """(header, record key, name) per hold: the clamp, each arm, each jig."""
    cols = [("clamp", "clamped_faces", "")] if holds.get("clamped_faces") is not None else []
    cols += [(f"arm {a}", "arms", a) for a in holds.get("arms") or {}]
    cols += [(f"jig {j}", "jigs", j) for j in holds.get("jigs") or {}]
    return cols


def state_rows(holds: dict) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of the per-state table: fold state, waypoints, one column per hold (the face
    it has), then the proof (held / what is free), nullity and the smallest singular value."""
    cols = _hold_columns(holds)
    header = ["fold state", "waypoints"] + [c[0] for c in cols] + ["holds proven", "nullity", "sigma_min"]
    rows = []
    for st in holds.get("states") or []:
        w0, w1 = st.get("waypoints", [0, 0])
        cells = []
        for _, key, name in cols:
            if key == "clamped_faces":
                cells.append(", ".join(map(str, holds["clamped_faces"])) or "—")
            else:
                f = (holds[key][name] or [None])[w0] if w0 < len(holds[key][name]) else None
                cells.append("—" if f is None else str(f))
        if st.get("ok"):
            proof = "yes" + (" (flat: crease cut)" if st.get("flat") else "")
        else:
            free = [f"crease {c}" for c in (st.get("unheld_creases") or [])] or \
                   [f"crease {c}" for c in (st.get("free_creases") or [])] or ["a free motion"]
            proof = "no: " + ", ".join(free) + " free"
        sig = st.get("sigma_min")
        rows.append([f"{float(st.get('state', 0)):g}", f"{w0}–{w1}", *cells, proof, str(st.get("nullity", "")),
                     "" if sig is None else f"{float(sig):.3g}"])
    return header, rows


def _table(table_id: str, header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td class='{'fail' if c.startswith(('FREE', 'no:')) else ''}'>{_e(c)}</td>"
                                    for c in r) + "</tr>" for r in rows)
    return f"<table id='{table_id}'><tr>{head}</tr>{body}</table>"


def holds_section(check: dict) -> str:
    """The section's HTML ("" when the check recorded no holds)."""
    holds = (check or {}).get("holds")
    if not isinstance(holds, dict) or not holds.get("states"):
        return ""
    from fabkit.held_faces import grip_changes

    parts = ["<h2>What folds each crease</h2>",
             "<p class='muted'>Each crease row cut: the holds on each side (clamp, each arm's grip, each jig), "
             "per run of moves with one set of holds, as <code>fabkit check</code> proved them.</p>",
             _table("crease-holds", ["crease", "waypoints", "fold states", "one side", "other side", "verdict"],
                    crease_rows(holds))]
    header, rows = state_rows(holds)
    parts += ["<h2>Held faces per fold state</h2>", _table("held-faces", header, rows)]
    changes = grip_changes(holds)
    if changes:
        parts.append("<ul id='grip-changes'>" + "".join(f"<li>{_e(c.text)}</li>" for c in changes) + "</ul>")
    return "\n".join(parts)
