"""The common verdict and JSON format of every reproduction (``clsas reproduce PAPER``).

A reproduction compares numbers a paper prints with the same numbers computed by clsas. It
builds one :class:`Report` and ends with :func:`finish`:

- a :class:`Row` per printed number: the paper's value, clsas's value, the tolerance within
  which they are said to match (absolute, in the row's unit) and, when they do not, the key of
  a :class:`Reason`;
- a :class:`Reason` per cause of a difference: what differs and why, with its evidence, each
  item either ``"experiment:NAME"`` (an :class:`Experiment` of the same report, run and printed
  by the reproduction) or ``"test:tests/FILE.py::NAME"`` (a test that fails if the explanation
  stops holding; tests/test_reproduce.py checks that each one named exists);
- an :class:`Experiment` per question asked of the difference (a window, an assumed parameter,
  a definition): what was varied, its table, what it showed;
- the assumed parameters (what the paper does not give), and timings of the stages.

Verdicts: ``match`` when |clsas - paper| <= tolerance; ``differs: KEY`` otherwise (:meth:`Report.check`
refuses a differing row without a reason, and a reason without evidence or naming an
experiment the report does not hold); ``clsas only`` for a row the paper has no number for.

Minimal use, in a reproduction module::

    from . import report

    def add_arguments(parser):
        ...                                  # the paper's own options
        report.add_arguments(parser)         # --json PATH

    def run(args):
        rep = report.Report("wu2018", "Wu, Tang & Zhong 2018, Table 2", assumptions=[...])
        rep.add("Table 2", "P1 none", "azimuth PSLR", "dB", paper=-8.10, clsas=4.03, tolerance=1.0,
                reason="angles")
        rep.explain("angles", "the paper's angles ...", evidence=["experiment:constant-angles"])
        rep.experiment("constant-angles", "Is Table 2 made with constant angles?", ("case", "PSLR"), rows,
                       "with constant 1.5 deg ...")
        return report.finish(rep, args)

``--json PATH`` writes :meth:`Report.to_dict` (format :data:`FORMAT`) atomically (a temporary
file beside PATH, then a rename); :func:`load` reads it back, and bench/validation.py builds
docs/validation.md from such files.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..version import __version__

FORMAT = "clsas-reproduction/1"
MATCH, DIFFERS, ONLY = "match", "differs", "clsas only"
KINDS = ("value", "at most", "at least")  # what a paper's number is (Row.kind)
BOUNDS = {"at most": "<=", "at least": ">="}  # how a bound is printed before the paper's number


@dataclass(frozen=True)
class Row:
    """One number of a paper beside clsas's.

    table : where the paper prints it ("Table 2", "section 4", "Fig. 7").
    item : what it is of ("T1", "P5, no correction").
    quantity : the measured quantity ("azimuth PSLR").
    unit : its unit ("dB", "m", "x").
    paper : the printed value (None: the paper gives none; the row is clsas's alone).
    clsas : clsas's value (NaN when clsas could not measure it; that differs).
    tolerance : the largest |clsas - paper| still called a match, in ``unit``.
    reason : the key of the :class:`Reason` a difference has, or several keys joined by ", "
        ("" when none is given).
    kind : ``"value"`` (the paper prints a value: match within ``tolerance`` either side), or
        ``"at most"`` / ``"at least"`` (the paper prints a bound, "errors of at most 2 mm": match
        when clsas is within it, up to ``tolerance`` beyond).
    """

    table: str
    item: str
    quantity: str
    unit: str
    paper: float | None
    clsas: float
    tolerance: float
    reason: str = ""
    kind: str = "value"

    @property
    def reason_keys(self) -> list:
        """The reason's keys (several when the difference has several causes)."""
        return [k.strip() for k in self.reason.split(",") if k.strip()]

    @property
    def difference(self) -> float | None:
        """clsas - paper (None without a paper value)."""
        return None if self.paper is None else self.clsas - self.paper

    @property
    def verdict(self) -> str:
        """:data:`MATCH`, :data:`DIFFERS` or :data:`ONLY`."""
        if self.paper is None:
            return ONLY
        d = self.difference
        if not math.isfinite(d):
            return DIFFERS
        within = {"value": abs(d), "at most": d, "at least": -d}[self.kind] <= self.tolerance
        return MATCH if within else DIFFERS

    @property
    def paper_text(self) -> str:
        """The paper's number as printed in a table: the value, or the bound ("<= 2")."""
        if self.paper is None:
            return "-"
        return f"{BOUNDS.get(self.kind, '')}{self.paper:.4g}"


@dataclass(frozen=True)
class Reason:
    """Why some rows differ: ``text`` says what and why; ``evidence`` items are
    ``"experiment:NAME"`` or ``"test:tests/FILE.py::NAME"``."""

    key: str
    text: str
    evidence: tuple = ()


@dataclass(frozen=True)
class Experiment:
    """A question asked of a difference, with its table: ``columns`` name the cells of each of
    ``rows`` (numbers or text), ``finding`` says what it showed."""

    name: str
    question: str
    columns: tuple
    rows: tuple
    finding: str


@dataclass
class Report:
    """A paper's numbers beside clsas's (module docstring). ``paper`` is the reproduction's
    name (``clsas reproduce PAPER``), ``title`` what it reproduces, ``assumptions`` what the
    paper does not give and clsas assumed, ``settings`` the options it ran with."""

    paper: str
    title: str
    assumptions: list = field(default_factory=list)
    settings: dict = field(default_factory=dict)
    rows: list = field(default_factory=list)
    reasons: dict = field(default_factory=dict)
    experiments: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    stages: list = field(default_factory=list)  # (name, seconds)
    started: float = field(default_factory=time.perf_counter, repr=False)
    load_at_start: list = field(default_factory=lambda: _load_average(), repr=False)

    def add(self, table: str, item: str, quantity: str, unit: str, paper, clsas, tolerance: float,
            reason: str = "", kind: str = "value") -> Row:
        """Append a :class:`Row` (numbers as float; ``paper`` None for clsas's own rows; ``kind``
        "at most" or "at least" when the paper prints a bound)."""
        if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance >= 0):
            raise ValueError(f"tolerance: must be a finite number >= 0, got {tolerance!r}")
        if kind not in KINDS:
            raise ValueError(f"kind: must be one of {KINDS}, got {kind!r}")
        row = Row(table, item, quantity, unit, None if paper is None else float(paper), float(clsas),
                  float(tolerance), reason, kind)
        self.rows.append(row)
        return row

    def explain(self, key: str, text: str, evidence) -> Reason:
        """Record the reason ``key`` (rows name it in their ``reason``)."""
        if isinstance(evidence, str):
            evidence = (evidence,)
        reason = Reason(key, " ".join(text.split()), tuple(evidence))
        self.reasons[key] = reason
        return reason

    def experiment(self, name: str, question: str, columns, rows, finding: str) -> Experiment:
        """Record an experiment's table (reasons cite it as ``"experiment:NAME"``)."""
        exp = Experiment(name, " ".join(question.split()), tuple(columns), tuple(tuple(r) for r in rows),
                         " ".join(finding.split()))
        self.experiments[name] = exp
        return exp

    def note(self, text: str) -> None:
        self.notes.append(" ".join(text.split()))

    def stage(self, name: str, estimate_s: float | None = None) -> "_Stage":
        """``with rep.stage("back-projection", estimate_s=40):`` prints the stage and its
        estimate on stderr before it starts and its time when it ends, and keeps the time."""
        return _Stage(self, name, estimate_s)

    def check(self) -> None:
        """A ValueError when a row differs without a known reason, a reason has no evidence, or
        its evidence names an experiment this report does not hold or is neither kind."""
        problems = []
        for row in self.rows:
            if row.verdict == DIFFERS and (not row.reason_keys or any(k not in self.reasons for k in row.reason_keys)):
                problems.append(f"{row.table} {row.item} {row.quantity} differs "
                                f"({row.clsas:g} vs {row.paper:g}) without a reason"
                                + (f" (unknown key {row.reason!r})" if row.reason else ""))
        for reason in self.reasons.values():
            if not reason.evidence:
                problems.append(f"reason {reason.key!r} has no evidence")
            for item in reason.evidence:
                kind, _, name = item.partition(":")
                if kind == "experiment" and name not in self.experiments:
                    problems.append(f"reason {reason.key!r} cites experiment {name!r}, which was not run")
                elif kind not in ("experiment", "test") or not name:
                    problems.append(f"reason {reason.key!r}: evidence {item!r} is neither 'experiment:NAME' nor "
                                    "'test:tests/FILE.py::NAME'")
        if problems:
            raise ValueError(f"reproduction {self.paper}: " + "; ".join(problems))

    def counts(self) -> dict:
        """{verdict: number of rows}."""
        out = {MATCH: 0, DIFFERS: 0, ONLY: 0}
        for row in self.rows:
            out[row.verdict] += 1
        return out

    def to_dict(self) -> dict:
        """The JSON document (:data:`FORMAT`)."""
        return {
            "format": FORMAT, "paper": self.paper, "title": self.title, "clsas": __version__,
            "machine": {**machine(), "load_average_at_start": self.load_at_start}, "settings": self.settings, "assumptions": list(self.assumptions),
            "seconds": time.perf_counter() - self.started,
            "stages": [{"name": n, "seconds": s} for n, s in self.stages],
            "counts": self.counts(),
            "rows": [{**asdict(r), "difference": r.difference, "verdict": r.verdict} for r in self.rows],
            "reasons": [asdict(r) for r in self.reasons.values()],
            "experiments": [asdict(e) for e in self.experiments.values()],
            "notes": list(self.notes),
        }

    def format(self) -> str:
        """The printed table: rows grouped by table, the verdict column, then the reasons, the
        experiments and the notes."""
        lines = [self.title]
        if self.assumptions:
            lines.append("assumed (not in the paper):")
            lines += [f"  - {a}" for a in self.assumptions]
        item_w = max([len(r.item) for r in self.rows] + [4])
        qty_w = max([len(f"{r.quantity} ({r.unit})") for r in self.rows] + [8])
        table = None
        for row in self.rows:
            if row.table != table:
                table = row.table
                lines += ["", f"{table}", f"  {'item':{item_w}}  {'quantity':{qty_w}}  {'paper':>9}  {'clsas':>9}  "
                                          f"{'diff':>8}  {'tol':>6}  verdict"]
            paper = row.paper_text
            diff = "" if row.difference is None else f"{row.difference:+8.3g}"
            verdict = row.verdict if row.verdict != DIFFERS else f"differs: {row.reason or '?'}"
            lines.append(f"  {row.item:{item_w}}  {row.quantity + ' (' + row.unit + ')':{qty_w}}  {paper:>9}  "
                         f"{row.clsas:9.4g}  {diff:>8}  {row.tolerance:6.3g}  {verdict}")
        counts = self.counts()
        lines += ["", f"verdicts: {counts[MATCH]} match, {counts[DIFFERS]} differ (each with its reason below), "
                      f"{counts[ONLY]} clsas only"]
        used = {k for r in self.rows if r.verdict == DIFFERS for k in r.reason_keys}
        for reason in self.reasons.values():
            tag = "" if reason.key in used else " (no row differs for it in this run)"
            lines += ["", f"why {reason.key}{tag}: {reason.text}", f"  evidence: {', '.join(reason.evidence)}"]
        for exp in self.experiments.values():
            lines += ["", f"experiment {exp.name}: {exp.question}", _grid(exp.columns, exp.rows),
                      f"  finding: {exp.finding}"]
        if self.notes:
            lines.append("")
            lines += [f"note: {n}" for n in self.notes]
        if self.stages:
            lines += ["", "time: " + ", ".join(f"{n} {s:.1f} s" for n, s in self.stages)
                      + f"; total {time.perf_counter() - self.started:.1f} s"]
        return "\n".join(lines)


class _Stage:
    def __init__(self, rep: Report, name: str, estimate_s: float | None):
        self.rep, self.name, self.estimate = rep, name, estimate_s

    def __enter__(self):
        extra = f" (estimated {self.estimate:.0f} s on 2 cores)" if self.estimate is not None else ""
        print(f"{self.rep.paper}: {self.name}{extra} ...", file=sys.stderr, flush=True)
        self.start = time.perf_counter()
        return self

    def __exit__(self, exc_type, *_):
        seconds = time.perf_counter() - self.start
        if exc_type is None:
            self.rep.stages.append((self.name, seconds))
            print(f"{self.rep.paper}: {self.name} done in {seconds:.1f} s", file=sys.stderr, flush=True)


def _cell(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _grid(columns, rows) -> str:
    cells = [[_cell(c) for c in columns]] + [[_cell(v) for v in row] for row in rows]
    widths = [max(len(r[k]) for r in cells if k < len(r)) for k in range(len(columns))]
    return "\n".join("  " + "  ".join(f"{c:>{w}}" for c, w in zip(r, widths)) for r in cells)


def _load_average() -> list | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def machine() -> dict:
    """Where a reproduction ran: processor, cores, the load average (1, 5, 15 min), Python."""
    return {"machine": platform.machine(), "processor": _cpu_name(), "cores": os.cpu_count(),
            "python": platform.python_version(), "load_average": _load_average()}


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def count(low: int):
    """An argparse type: an integer >= ``low`` (argparse names the option in its error)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {text!r}")
        return value
    return parse


def finite(text: str) -> float:
    """An argparse type: a finite real number (argparse names the option in its error)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every reproduction shares: ``--json PATH``."""
    parser.add_argument("--json", metavar="PATH", default=None,
                        help="also write the table, the reasons and the experiments as JSON to PATH")


def _json_path(path) -> Path:
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"--json {path}: is a directory; give a file name")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"--json {path}: the folder {path.parent} does not exist")
    return path


def write_json(rep: Report, path) -> Path:
    """Write ``rep.to_dict()`` to ``path`` through a temporary file beside it and a rename."""
    path = _json_path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(rep.to_dict(), f, indent=1, allow_nan=True)
            f.write("\n")
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def check_output(args: argparse.Namespace) -> None:
    """Refuse a bad ``--json`` path before the reproduction computes anything."""
    if getattr(args, "json", None) is not None:
        _json_path(args.json)


def finish(rep: Report, args: argparse.Namespace) -> int:
    """Check ``rep`` (:meth:`Report.check`), print it, write ``--json``; returns 0."""
    rep.check()
    print(rep.format())
    if getattr(args, "json", None):
        print(f"\nJSON: {write_json(rep, args.json)}")
    return 0


def load(path) -> dict:
    """A report written by ``--json`` (the dict of :meth:`Report.to_dict`); a ValueError naming
    the file when it is not one."""
    path = Path(path)
    with open(path, encoding="utf-8") as f:
        try:
            doc = json.load(f)
        except json.JSONDecodeError as err:
            raise ValueError(f"{path}: not a reproduction report ({err})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{path}: not a reproduction report (format {FORMAT!r} expected)")
    return doc
