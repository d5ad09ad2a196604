"""sinc8 back-projection before and after the unit-sum tap table (issue 31 item 3), interleaved.

Commit 3806aee ("One interpolation module") replaced back-projection's own sinc8 table (2049
rows, not normalised, taps stored twice) by interp.py's unit-sum table (4097 rows). This script
exports that commit's parent (``before``), the commit (``unit-sum``) and runs them beside this
tree (``now``) on bench_backprojection's scene with ``interp="sinc8"`` (each tree's own bench
scene and ``backproject``), one process per tree and round, the trees interleaved (A B C, A B
C, ...), each process timing ``--calls`` calls after a warm-up call. Reports min and median per
tree and the ratios to ``before``. Needs git and the repository's history; not in run_all (it
rebuilds old trees' kernels).

    python bench/history_sinc8.py [--quick] [--json] [--repeats ROUNDS]
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _harness import arguments, report

ROOT = Path(__file__).resolve().parent.parent
TREES = {"before": "3806aee~1", "unit-sum": "3806aee"}
CALLS = 5
ONE_RUN = """
import json, sys, time
root, n_pix, n_pulses, calls = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
sys.path[:0] = [root, root + "/bench"]
import clsas, bench_backprojection as b
assert clsas.__file__.startswith(root), clsas.__file__
echo, grid = b.scene(n_pulses, 4096, n_pix)
run = lambda: b.backproject(echo, grid, backend="opencl", interp="sinc8", upsample=1, progress=False)
run()
times = []
for _ in range(calls):
    start = time.perf_counter()
    run()
    times.append(time.perf_counter() - start)
print(json.dumps(times))
"""


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n_pix, n_pulses = (128, 128) if args.quick else (256, 256)
    rounds = args.repeats or (2 if args.quick else 5)
    with tempfile.TemporaryDirectory(prefix="clsas-sinc8-") as tmp:
        roots = {}
        for name, commit in TREES.items():
            roots[name] = Path(tmp) / name
            roots[name].mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], check=True, capture_output=True)
            subprocess.run(["tar", "-x", "-C", str(roots[name])], input=archive.stdout, check=True)
        roots["now"] = ROOT
        times = {name: [] for name in roots}
        for _ in range(rounds):
            for name, root in roots.items():
                out = subprocess.run([sys.executable, "-c", ONE_RUN, str(root), str(n_pix), str(n_pulses), str(CALLS)],
                                     check=True, capture_output=True, text=True, cwd=tmp)
                times[name] += json.loads(out.stdout.splitlines()[-1])
    work = n_pix * n_pix * n_pulses / 1e9
    for name, t in times.items():
        med = statistics.median(t)
        report(args, "sinc8-history", "opencl", {"pixels": n_pix * n_pix, "pulses": n_pulses, "receivers": 1,
                                                  "samples": 4096},
               work / med, "G backprojections/s", med, case=name, tree=TREES.get(name, "this tree"),
               min_seconds=min(t), runs=len(t), speed_vs_before_median=statistics.median(times["before"]) / med,
               speed_vs_before_min=min(times["before"]) / min(t))


if __name__ == "__main__":
    main()
