"""`python -m bench [NAME ...]`: run every bench/bench_*.py (or the named ones).

Each benchmark module has `main() -> dict`: it prints a table, compares against a baseline in the
same run (a ratio) and writes JSON to bench/results/<name>.json.
"""
import importlib
import pkgutil
import sys
import time
import traceback
from pathlib import Path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    here = Path(__file__).parent
    names = sorted(m.name for m in pkgutil.iter_modules([str(here)]) if m.name.startswith("bench_"))
    if argv:
        names = [n for n in names if any(a in n for a in argv)]
    (here / "results").mkdir(exist_ok=True)
    failed = []
    for name in names:
        print(f"== {name}")
        t0 = time.perf_counter()
        try:
            importlib.import_module(f"bench.{name}").main()
        except Exception as exc:  # keep running the others, report at the end
            traceback.print_exc()
            failed.append(f"{name}: {type(exc).__name__}: {exc}")
        print(f"   ({time.perf_counter() - t0:.1f} s)")
    for f in failed:
        print("FAILED", f)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
