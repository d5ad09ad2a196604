"""Run every bench/bench_*.py with --json (pass --quick through) and print one table."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    quick = "--quick" in sys.argv[1:]
    rows, failed = [], []
    for script in sorted(HERE.glob("bench_*.py")):
        cmd = [sys.executable, str(script), "--json"] + (["--quick"] if quick else [])
        print(f"running {script.name} ...", file=sys.stderr, flush=True)
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            failed.append(script.name)
            print(result.stderr, file=sys.stderr)
            continue
        rows += [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    print(f"{'bench':16s} {'backend':8s} {'rate':>12s} {'unit':18s} {'seconds':>10s}  size / case")
    for r in rows:
        extra = {k: v for k, v in r.items() if k not in ("bench", "backend", "device", "size", "rate", "unit", "seconds")}
        print(f"{r['bench']:16s} {r['backend']:8s} {r['rate']:12.4g} {r['unit']:18s} {r['seconds']:10.4f}  "
              f"{r['size']} {extra if extra else ''}")
    if failed:
        print("FAILED:", ", ".join(failed), file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
