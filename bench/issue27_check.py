"""Issue #27's text, walked one reproducer at a time against the checkout this runs from.

Each check is one sentence of the issue (its reproducer, as written there, on the fuzz's tiny
scenes) and what the project's rule wants of it: the named error (TypeError for a wrong kind,
ValueError naming the parameter, DataFileError/OSError naming the path, EstimationError,
MemoryBudgetError before the allocation) or the right result. A check that fails prints what
happened instead, with the owner of the code it sits in.

    python bench/issue27_check.py                 # every check, ~1-2 min on 2 cores
    python bench/issue27_check.py -k budget cli   # the checks whose name holds a word
    python bench/issue27_check.py --json out.json
    python bench/issue27_check.py -k heavy        # the 10 GiB huang2022 run (minutes, ~12 GB)

Exit status 0 when every check passes, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import _issue27_api  # noqa: E402,F401  (registers its checks)
import _issue27_files  # noqa: E402,F401  (registers its checks)
import clsas  # noqa: E402
from _issue27 import CHECKS, Failed  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", nargs="+", default=None,
                        help="run the checks whose section or name holds a word (the heavy ones only so)")
    parser.add_argument("--json", default=None, help="write the outcomes there")
    args = parser.parse_args()
    chosen = [c for c in CHECKS if (args.k is None and c[0] != "heavy") or
              args.k is not None and any(w in c[0] or w in c[1] for w in args.k)]
    rows = []
    for section, name, owner, fn in chosen:
        start = time.perf_counter()
        try:
            with clsas.use_memory_budget(clsas.memory_budget()):
                fn()
            outcome = None
        except Failed as err:
            outcome = str(err)
        except Exception as err:  # noqa: BLE001 - the check itself broke: a failure too
            outcome = f"the check broke: {type(err).__name__}: {str(err)[:200]}"
        seconds = time.perf_counter() - start
        rows.append(dict(section=section, check=name, owner=owner, issue=" ".join(fn.__doc__.split()),
                         passed=outcome is None, outcome=outcome, seconds=round(seconds, 2)))
        print(f"{'ok  ' if outcome is None else 'FAIL'} [{owner}] {section}: {name} ({seconds:.1f} s)"
              + ("" if outcome is None else f"\n       {outcome}"), flush=True)
    failed = [r for r in rows if not r["passed"]]
    by_owner = {}
    for r in failed:
        by_owner[r["owner"]] = by_owner.get(r["owner"], 0) + 1
    print(f"{len(rows) - len(failed)} of {len(rows)} checks pass; failing by owner: "
          + (", ".join(f"{k} {v}" for k, v in sorted(by_owner.items())) or "none"))
    if args.json:
        Path(args.json).write_text(json.dumps({"load": os.getloadavg(), "checks": rows}, indent=1))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
