"""Write docs/validation.md: every reproduction's table (paper beside clsas, verdicts, reasons,
experiments) and every bench's figures, from their JSON.

    python bench/validation.py              # run the reproductions and the benches, then write the page
    python bench/validation.py --quick      # the benches with --quick (the reproductions run their defaults)
    python bench/validation.py --render     # only rewrite the page from the JSON already in docs/validation/
    python bench/validation.py --papers huang2022 wu2018 --no-benches

The JSON lives in docs/validation/: PAPER.json per reproduction (``clsas reproduce PAPER --json``,
clsas/reproduce/report.py's format) and benches.jsonl (one line per figure, bench/_harness.py's
format). A reproduction whose command has no ``--json`` yet is listed as such. The page is
written to a temporary file and renamed.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

from clsas.reproduce import paper_names, report  # noqa: E402

DATA = ROOT / "docs" / "validation"
PAGE = ROOT / "docs" / "validation.md"


def arguments(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--render", action="store_true", help="only rewrite the page from docs/validation/*.json")
    parser.add_argument("--quick", action="store_true", help="run the benches with --quick")
    parser.add_argument("--papers", nargs="*", default=None, help="reproductions to run (default: all)")
    parser.add_argument("--no-benches", action="store_true", help="do not run the benches")
    parser.add_argument("--data", type=Path, default=DATA, help="folder of the JSON (default docs/validation)")
    parser.add_argument("--out", type=Path, default=PAGE, help="the page (default docs/validation.md)")
    return parser.parse_args(argv)


def _clsas(*args, cwd=ROOT, **kwargs) -> subprocess.CompletedProcess:
    """``python -m clsas ARGS`` of this checkout (on the path whatever the working folder)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, (str(ROOT), os.environ.get("PYTHONPATH")))))
    return subprocess.run([sys.executable, "-m", "clsas", "--no-progress", *args], cwd=cwd, env=env, text=True,
                          **kwargs)


def takes_json(paper: str) -> bool:
    """Whether ``clsas reproduce PAPER`` has the common ``--json`` option."""
    return "--json" in _clsas("reproduce", paper, "--help", capture_output=True).stdout


def run_papers(papers, data: Path) -> None:
    for paper in papers:
        if not takes_json(paper):
            print(f"{paper}: no --json option yet; skipped", file=sys.stderr)
            continue
        print(f"{paper}: running clsas reproduce {paper} --json ...", file=sys.stderr, flush=True)
        # --overwrite: the run replaces the last one's table (written to a temporary name and renamed,
        # so a failed run leaves it as it was); run in a temporary folder: the figures a reproduction
        # draws by default (reproduce-PAPER/) are not the page's, which reads only the JSON
        with tempfile.TemporaryDirectory(prefix=f"clsas-{paper}-") as scratch:
            done = _clsas("reproduce", paper, "--json", str(data.resolve() / f"{paper}.json"), "--overwrite",
                          cwd=scratch, stdout=subprocess.DEVNULL)
        if done.returncode != 0:
            print(f"{paper}: failed (exit {done.returncode})", file=sys.stderr)


def run_benches(quick: bool, data: Path) -> None:
    lines = []
    for script in sorted(HERE.glob("bench_*.py")):
        print(f"{script.name} ...", file=sys.stderr, flush=True)
        done = subprocess.run([sys.executable, str(script), "--json", *(["--quick"] if quick else [])], cwd=ROOT,
                              capture_output=True, text=True)
        if done.returncode != 0:
            print(f"{script.name}: failed (exit {done.returncode})\n{done.stderr[-2000:]}", file=sys.stderr)
            continue
        lines += [line for line in done.stdout.splitlines() if line.startswith("{")]
    _write(data / "benches.jsonl", "\n".join(lines) + "\n")


def _write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value).replace("|", "\\|")


def _table(columns, rows) -> list:
    return ["| " + " | ".join(_cell(c) for c in columns) + " |", "|" + "---|" * len(columns)] + \
        ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]


def _paper(row: dict) -> str:
    """The paper's number of a row as printed: the value, or its bound ("<=2")."""
    if row["paper"] is None:
        return "-"
    return report.BOUNDS.get(row.get("kind", "value"), "") + _cell(row["paper"])


def _machine(doc: dict) -> str:
    m = doc.get("machine", {})
    start, end = m.get("load_average_at_start"), m.get("load_average")
    load = f", load {start[0]} -> {end[0]}" if start and end else (f", load {end[0]}" if end else "")
    return f"{m.get('processor', '?')}, {m.get('cores', '?')} cores{load}"


def render_paper(doc: dict) -> list:
    lines = [f"## {doc['paper']}: {doc['title']}", ""]
    counts = doc["counts"]
    lines.append(f"{counts['match']} rows match, {counts['differs']} differ (each with its reason), "
                 f"{counts['clsas only']} clsas only; ran {doc['seconds']:.0f} s on {_machine(doc)}; clsas "
                 f"{doc['clsas']}; settings {doc['settings']}.")
    if doc["assumptions"]:
        lines += ["", "Assumed (the paper does not give it):", ""] + [f"- {a}" for a in doc["assumptions"]]
    tables = []
    for row in doc["rows"]:
        if row["table"] not in tables:
            tables.append(row["table"])
    for name in tables:
        rows = [(r["item"], f"{r['quantity']} ({r['unit']})", _paper(r), r["clsas"], r["difference"], r["tolerance"],
                 r["verdict"] if r["verdict"] != "differs" else f"differs: {r['reason']}")
                for r in doc["rows"] if r["table"] == name]
        lines += ["", f"### {name}", ""] + _table(("item", "quantity", "paper", "clsas", "diff", "tol", "verdict"), rows)
    if doc["reasons"]:
        lines += ["", "### Why rows differ", ""]
        for reason in doc["reasons"]:
            lines.append(f"- **{reason['key']}**: {reason['text']} Evidence: {', '.join(reason['evidence'])}.")
    for exp in doc["experiments"]:
        lines += ["", f"### Experiment {exp['name']}", "", exp["question"], ""] + _table(exp["columns"], exp["rows"])
        lines += ["", f"Finding: {exp['finding']}"]
    if doc["notes"]:
        lines += [""] + [f"Note: {n}" for n in doc["notes"]]
    return lines + [""]


def render_benches(rows: list) -> list:
    lines = ["## Benches", "", "Each figure is one line of a bench's `--json` output (bench/_harness.py); compare "
             "ratios within one run only (docs/design.md).", ""]
    table = []
    for r in rows:
        extra = {k: v for k, v in r.items()
                 if k not in ("bench", "backend", "device", "size", "rate", "unit", "seconds", "machine")}
        case = ", ".join(f"{k} {_cell(v)}" for k, v in {**r.get("size", {}), **extra}.items())
        load = (r.get("machine") or {}).get("load_average")
        device = r.get("device", "")
        if (r.get("machine") or {}).get("kernels") == "avx2":
            device += " (kernels built for AVX2 on an AVX-512 CPU: --kernels avx2)"
        table.append((r["bench"], r["backend"], r["rate"], r["unit"], r["seconds"], case, device,
                      load[0] if load else "-"))
    return lines + _table(("bench", "backend", "rate", "unit", "seconds", "case", "device", "load"), table) + [""]


def render(data: Path) -> str:
    names = paper_names()
    docs, missing = [], []
    for name in names:
        path = data / f"{name}.json"
        if path.exists():
            docs.append(report.load(path))
        else:
            missing.append(name)
    lines = ["# Validation: the source papers reproduced, and the benches", "",
             f"Generated by `python bench/validation.py` on {datetime.date.today().isoformat()} from the JSON in "
             "docs/validation/ (do not edit by hand: rerun the script). Each reproduction's rows put the paper's "
             "number beside clsas's with a tolerance; a row that differs names its reason, and each reason its "
             "evidence: an experiment printed below it, or a test.", "", "## Summary", ""]
    summary = [(d["paper"], d["title"], len(d["rows"]), d["counts"]["match"], d["counts"]["differs"],
                d["counts"]["clsas only"], f"{d['seconds']:.0f} s", _machine(d)) for d in docs]
    summary += [(name, "no JSON in docs/validation/ yet (run `python bench/validation.py --papers " + name + "`)"
                 if takes_json(name) else "not in the common format yet (no --json)", "-", "-", "-", "-", "-", "-")
                for name in missing]
    lines += _table(("paper", "what", "rows", "match", "differ", "clsas only", "time", "machine"), summary) + [""]
    for doc in docs:
        lines += render_paper(doc)
    bench_file = data / "benches.jsonl"
    if bench_file.exists():
        rows = [json.loads(line) for line in bench_file.read_text(encoding="utf-8").splitlines() if line.strip()]
        lines += render_benches(rows)
    return "\n".join(lines)


def main(argv=None) -> int:
    args = arguments(argv)
    args.data.mkdir(parents=True, exist_ok=True)
    if not args.render:
        run_papers(args.papers if args.papers is not None else paper_names(), args.data)
        if not args.no_benches:
            run_benches(args.quick, args.data)
    _write(args.out, render(args.data))
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
