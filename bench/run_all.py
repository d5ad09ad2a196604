"""Run every bench/bench_*.py with --json (pass --quick through), print one table and write every
row, with the machine it was measured on (bench/_harness.py), to one JSON file (``--out``,
default bench-results.json in the current folder).

    python bench/run_all.py [--quick] [--kernels avx2] [--out FILE] [--only NAME ...]

``--kernels avx2`` (passed through): the kernels built as on an AVX2 CPU (bench/_harness.py).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _harness import kernels_for_avx2, machine, machine_brief

HERE = Path(__file__).resolve().parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="each bench's quick size")
    parser.add_argument("--out", default="bench-results.json", help="the JSON file of every row")
    parser.add_argument("--only", nargs="*", default=None, help="bench stems to run (e.g. backprojection ffbp)")
    parser.add_argument("--kernels", choices=("native", "avx2"), default="native",
                        help="the instruction set the OpenCL kernels are built for (bench/_harness.py)")
    args = parser.parse_args()
    if args.kernels == "avx2":
        kernels_for_avx2()  # so that the machine described at the start is the benches' one
    rows, failed = [], []
    started = machine()
    for script in sorted(HERE.glob("bench_*.py")):
        if args.only and script.stem.removeprefix("bench_") not in args.only:
            continue
        cmd = [sys.executable, str(script), "--json", "--kernels", args.kernels] + (["--quick"] if args.quick else [])
        print(f"running {script.name} ...", file=sys.stderr, flush=True)
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            failed.append(script.name)
            print(result.stderr, file=sys.stderr)
            continue
        rows += [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    print(f"machine at the start: {machine_brief(started)}")
    print(f"{'bench':16s} {'backend':8s} {'rate':>12s} {'unit':18s} {'seconds':>10s}  size / case")
    for r in rows:
        extra = {k: v for k, v in r.items()
                 if k not in ("bench", "backend", "device", "size", "rate", "unit", "seconds", "machine")}
        load = r.get("machine", {}).get("load_average", ["?"])[0]
        print(f"{r['bench']:16s} {r['backend']:8s} {r['rate']:12.4g} {r['unit']:18s} {r['seconds']:10.4f}  "
              f"{r['size']} {extra if extra else ''} load {load}")
    report = {"machine": started, "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "quick": args.quick,
              "rows": rows, "failed": failed}
    out = Path(args.out)
    with tempfile.NamedTemporaryFile("w", dir=out.resolve().parent, prefix=out.name, suffix=".tmp", delete=False) as f:
        json.dump(report, f, indent=1)
    os.replace(f.name, out)
    print(f"wrote {len(rows)} rows to {out}", file=sys.stderr)
    if failed:
        print("FAILED:", ", ".join(failed), file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
