"""`python -m bench.compare_verdicts BEFORE.json AFTER.json`: do two production runs' manifests
(`FABKIT_BENCH_MANIFEST` of `python -m bench production`) give the same verdicts?

Compares per panel the final stage and reason, and per set-up (clamped face, grip face, face up)
the stage and reason, with the cup refusal's note on when it ran (before planning, before the
refold) taken out of the reasons. Prints the counts and every difference; exits 1 on any.
"""
from __future__ import annotations

import json
import re
import sys

_WHEN = re.compile(r" \(the cup check, run before (planning: no program was planned or checked|the refold: nothing "
                   r"was refolded, planned or checked)\)")


def _plain(reason: str) -> str:
    return _WHEN.sub(" (the cup check)", reason or "")


def verdicts(path: str) -> tuple[dict, dict]:
    """({panel: (stage, reason)}, {(panel, clamp, grip, face up): (stage, reason)}) of a manifest."""
    panels = json.loads(open(path).read())["panels"]
    final, setups = {}, {}
    for name, e in panels.items():
        final[name] = (e.get("stage"), _plain(e.get("reason", "")))
        for s in e.get("setups") or ():
            key = (name, s["clamped_face"], s["grip_face"], s["face_up_on_fixture"])
            setups[key] = (s["stage"], _plain(s["reason"]))
    return final, setups


def main(argv=None) -> int:
    before, after = (argv or sys.argv[1:])[:2]
    (f0, s0), (f1, s1) = verdicts(before), verdicts(after)
    cup = lambda s: {k for k, v in s.items() if "(the cup check)" in v[1] and v[0] == "check"}  # noqa: E731
    print(f"panels {len(f0)} / {len(f1)}; ok {sum(v[0] is None for v in f0.values())} / "
          f"{sum(v[0] is None for v in f1.values())}; set-ups {len(s0)} / {len(s1)}; "
          f"cup-refused set-ups {len(cup(s0))} / {len(cup(s1))}")
    diff = [(k, f0.get(k), f1.get(k)) for k in sorted(set(f0) | set(f1)) if f0.get(k) != f1.get(k)]
    sdiff = [(k, s0.get(k), s1.get(k)) for k in sorted(set(s0) | set(s1), key=str) if s0.get(k) != s1.get(k)]
    for k, a, b in diff:
        print("panel", k, "\n  before:", a, "\n  after: ", b)
    for k, a, b in sdiff:
        print("set-up", k, "\n  before:", a, "\n  after: ", b)
    same_cup = cup(s0) == cup(s1)
    print(f"final verdicts identical: {not diff}; set-up verdicts identical: {not sdiff}; "
          f"cup-refused (panel, set-up) pairs identical: {same_cup}")
    return 0 if not diff and not sdiff and same_cup else 1


if __name__ == "__main__":
    sys.exit(main())
