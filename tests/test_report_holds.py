"""report.html's holds tables for any number of arms: one column per arm and jig, a free crease
and a set crease said as such (a CHECK.json `holds` record of a two-arm regrip program)."""
from __future__ import annotations

import json

from browser import table_rows
from fabkit.report.html import write_report_html


def two_arm_record() -> dict:
    side = lambda faces, holds: {"faces": faces, "holds": holds}  # noqa: E731
    return {
        "ok": False, "clamped_faces": [4],
        "arms": {"a": [None, 7, 7, None, None], "b": [None, None, 12, 12, None]},
        "jigs": {"pad": [1, 1, 1, 1, 1]},
        "states": [
            {"state": 0.0, "waypoints": [1, 1], "held_faces": [1, 4, 7], "ok": True, "flat": True, "nullity": 3,
             "sigma_min": 0.0},
            {"state": 1.0, "waypoints": [2, 2], "held_faces": [1, 4, 7, 12], "ok": True, "flat": False,
             "nullity": 0, "sigma_min": 0.012},
            {"state": 2.0, "waypoints": [3, 3], "held_faces": [1, 4, 12], "ok": False, "flat": False,
             "unheld_creases": [2], "nullity": 1, "sigma_min": 0.0},
        ],
        "creases": [
            {"waypoints": [2, 2], "states": [0.0, 1.0],
             "holds": ["clamp face 4", "arm a face 7", "arm b face 12", "jig pad face 1"],
             "creases": [
                 {"crease": 0, "edges": 3, "held": True, "set": True, "angle_deg": [30.0, 30.0],
                  "sides": [side([0, 1, 2, 3], ["jig pad face 1"]), side(list(range(4, 16)), ["clamp face 4"])]},
                 {"crease": 1, "edges": 3, "held": True, "set": False, "angle_deg": [0.0, 45.0],
                  "sides": [side(list(range(0, 8)), ["jig pad face 1", "clamp face 4", "arm a face 7"]),
                            side(list(range(8, 16)), ["arm b face 12"])]}]},
            {"waypoints": [3, 3], "states": [1.0, 2.0], "holds": ["clamp face 4", "arm b face 12", "jig pad face 1"],
             "creases": [
                 {"crease": 2, "edges": 3, "held": False, "set": False, "angle_deg": [10.0, 20.0],
                  "sides": [side([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 14], ["clamp face 4"]),
                            side([12, 13, 15], [])]}]},
        ]}


def test_holds_tables_for_two_arms_and_a_jig(tmp_path):
    (tmp_path / "check.json").write_text(json.dumps({"format": "fabkit.check/2", "ok": False,
                                                     "holds": two_arm_record()}))
    page = write_report_html(tmp_path, {"stages": []}).read_text()
    creases = table_rows(page, "What folds each crease")
    assert creases[1] == ["0", "2–2", "0–1", "faces 0–3: jig pad face 1", "faces 4–15: clamp face 4",
                          "set earlier: locked at 30.0°"]
    assert creases[2][5] == ("folded 0.0° → 45.0° between jig pad face 1 + clamp face 4 + arm a face 7 and "
                             "arm b face 12")
    assert creases[3][3:] == ["faces 0–11, 14: clamp face 4", "faces 12, 13, 15: nothing",
                              "FREE: faces 12, 13, 15 held by nothing"]
    states = table_rows(page, "Held faces per fold state")
    assert states[0] == ["fold state", "waypoints", "clamp", "arm a", "arm b", "jig pad", "holds proven", "nullity",
                         "sigma_min"]
    assert states[1][2:7] == ["4", "7", "—", "1", "yes (flat: crease cut)"]
    assert states[2][2:7] == ["4", "7", "12", "1", "yes"]
    assert states[3][2:7] == ["4", "—", "12", "1", "no: crease 2 free"]
    assert "waypoint 1: arm b grips face 12" in page and "waypoint 2: arm a releases face 7" in page
