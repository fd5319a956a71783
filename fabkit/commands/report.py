"""`fabkit report DIR`: report.html for any run folder (the stages' JSON reports, plots and files)."""
from __future__ import annotations

from fabkit.commands._common import add_common, say

HELP = """Write DIR/report.html for a run: one table row per stage report found in DIR (the JSON files
written with --report by relax, unfold, refold, toolpath, check, panels, info; a demo's
summary.json), their numbers, the plots that can be drawn from them (relax history, joint angles,
clearance) and the pictures in DIR, and a list of every file. Self-contained: no network.

Exit codes: 0 written; 1 DIR has no fabkit report (the page is written, saying so); 2 DIR does not
exist.

example:
  fabkit relax p.obj -o r.obj --report relax.json && fabkit unfold r.obj -o f.obj --report unfold.json
  fabkit report .
"""


def add_arguments(parser) -> None:
    parser.add_argument("directory", metavar="DIR", help="run folder with the stages' JSON reports")
    add_common(parser)


def plan_files(args, plan) -> None:
    import os

    plan.output(os.path.join(args.directory, "report.html") if os.path.isdir(args.directory) else None,
                "report.html")
    plan.output(getattr(args, "report", None), "--report")


def run(args) -> int:
    from pathlib import Path

    from fabkit.errors import InputError
    from fabkit.report.html import write_report_html
    from fabkit.report.run import summarize_run

    out = Path(args.directory)
    if not out.is_dir():
        raise InputError("no such directory", source=args.directory)
    summary = summarize_run(out)
    target = write_report_html(out, summary)
    n = len(summary["stages"])
    say(args, f"wrote {target}: {n} stage report(s)" + (f" ({', '.join(s['name'] for s in summary['stages'])})"
                                                          if n else ""))
    if not n:
        import sys

        print(f"fabkit report: {args.directory}: no fabkit JSON report found (run the stages with --report)",
              file=sys.stderr)
        return 1
    return 0
