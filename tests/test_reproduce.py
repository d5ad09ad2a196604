"""The reproductions' common format (clsas/reproduce/report.py): verdicts, the check that every
difference has a reason with evidence, the JSON file, and that every test a reason cites exists."""

from __future__ import annotations

import argparse
import ast
import json
import math
import re
import subprocess
from pathlib import Path

import pytest

from clsas import reproduce
from clsas.reproduce import report

ROOT = Path(__file__).resolve().parent.parent


def _report() -> report.Report:
    rep = report.Report("demo", "a demo table", assumptions=["c = 1500 m/s"])
    rep.add("Table 1", "T1", "PSLR", "dB", paper=-13.3, clsas=-13.1, tolerance=0.5)
    rep.add("Table 1", "T2", "PSLR", "dB", paper=-14.0, clsas=-11.0, tolerance=0.5, reason="window")
    rep.add("Table 1", "T3", "ISLR", "dB", paper=None, clsas=-10.0, tolerance=0.0)
    rep.explain("window", "the paper weights the band", ["experiment:window"])
    rep.experiment("window", "Which window?", ("window", "PSLR"), [("none", -13.3), ("hamming", -42.0)],
                   "hamming gives the paper's figure")
    return rep


def test_verdicts_follow_the_tolerance():
    rows = _report().rows
    assert [r.verdict for r in rows] == [report.MATCH, report.DIFFERS, report.ONLY]
    assert rows[0].difference == pytest.approx(0.2) and rows[2].difference is None
    nan = report.Row("T", "x", "q", "dB", paper=1.0, clsas=math.nan, tolerance=10.0)
    assert nan.verdict == report.DIFFERS  # a value clsas could not measure never matches


def test_a_paper_bound_matches_on_its_side():
    """A row whose paper prints a bound ("errors of at most 2 mm"): a match on its side (up to
    the tolerance beyond), a difference past it; printed and rendered with the bound's sign."""
    rep = report.Report("demo", "bounds")
    below = rep.add("5.5", "sway", "max error", "mm", paper=2.0, clsas=0.6, tolerance=0.0, kind="at most")
    above = rep.add("5.5", "sway", "max error", "mm", paper=2.0, clsas=2.3, tolerance=0.2, kind="at most", reason="r")
    edge = rep.add("5.5", "sway", "max error", "mm", paper=2.0, clsas=2.1, tolerance=0.2, kind="at most")
    least = rep.add("5.5", "snr", "margin", "dB", paper=10.0, clsas=9.0, tolerance=0.5, kind="at least", reason="r")
    assert [r.verdict for r in (below, above, edge, least)] == [report.MATCH, report.DIFFERS, report.MATCH,
                                                                report.DIFFERS]
    assert below.paper_text == "<=2" and least.paper_text == ">=10"
    assert "<=2" in rep.format()
    with pytest.raises(ValueError, match="kind: must be one of"):
        rep.add("5.5", "sway", "max error", "mm", paper=2.0, clsas=0.6, tolerance=0.0, kind="below")
    validation = _validation_script()
    rows = validation.render_paper({**rep.to_dict(), "seconds": 1.0})
    assert any("| sway | max error (mm) | <=2 | 0.6 |" in line for line in rows), rows


def test_check_refuses_a_difference_without_a_reason_or_evidence():
    rep = _report()
    rep.check()
    rep.add("Table 1", "T4", "PSLR", "dB", paper=-14.0, clsas=-10.0, tolerance=0.5)
    with pytest.raises(ValueError, match="T4 PSLR differs .* without a reason"):
        rep.check()
    rep = _report()
    rep.explain("window", "no evidence", [])
    with pytest.raises(ValueError, match="no evidence"):
        rep.check()
    rep = _report()
    rep.explain("window", "cites nothing run", ["experiment:missing"])
    with pytest.raises(ValueError, match="'missing', which was not run"):
        rep.check()
    rep = _report()
    rep.explain("window", "bad kind", ["a hunch"])
    with pytest.raises(ValueError, match="neither"):
        rep.check()
    with pytest.raises(ValueError, match="tolerance"):
        rep.add("Table 1", "T5", "PSLR", "dB", paper=1.0, clsas=1.0, tolerance=math.nan)


def test_a_row_may_have_several_reasons():
    rep = _report()
    rep.add("Table 1", "T4", "PSLR", "dB", paper=-14.0, clsas=-10.0, tolerance=0.5, reason="window, other")
    with pytest.raises(ValueError, match="unknown key 'window, other'"):
        rep.check()
    rep.explain("other", "a second cause", ["test:tests/test_reproduce.py::test_a_row_may_have_several_reasons"])
    rep.check()
    assert rep.rows[-1].reason_keys == ["window", "other"] and "differs: window, other" in rep.format()


def test_printed_table_has_the_verdict_column_and_the_reasons():
    text = _report().format()
    assert "differs: window" in text and "match" in text and "clsas only" in text
    assert "why window: the paper weights the band" in text and "experiment window: Which window?" in text
    assert "1 match, 1 differ" in text and "c = 1500 m/s" in text


def test_json_round_trip_is_atomic(tmp_path, capsys):
    rep = _report()
    path = tmp_path / "demo.json"
    assert report.finish(rep, argparse.Namespace(json=str(path))) == 0
    doc = report.load(path)
    assert doc["format"] == report.FORMAT and doc["paper"] == "demo"
    assert [r["verdict"] for r in doc["rows"]] == ["match", "differs", "clsas only"]
    assert doc["counts"] == {"match": 1, "differs": 1, "clsas only": 1}
    assert doc["experiments"][0]["rows"] == [["none", -13.3], ["hamming", -42.0]]
    assert "load_average" in doc["machine"] and doc["assumptions"] == ["c = 1500 m/s"]
    assert "differs: window" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


def test_json_path_is_checked_before_the_work(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        report.check_output(argparse.Namespace(json=str(tmp_path / "no" / "x.json")))
    with pytest.raises(IsADirectoryError, match="is a directory"):
        report.check_output(argparse.Namespace(json=str(tmp_path)))
    report.check_output(argparse.Namespace(json=None))


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "r.json"
    path.write_text("old")
    monkeypatch.setattr(report.json, "dump", lambda *a, **k: (_ for _ in ()).throw(OSError("disk full")))
    with pytest.raises(OSError, match="disk full"):
        report.write_json(_report(), path)
    assert path.read_text() == "old" and list(tmp_path.iterdir()) == [path]


def test_load_refuses_other_files(tmp_path):
    bad = tmp_path / "x.json"
    bad.write_text(json.dumps({"bench": "x"}))
    with pytest.raises(ValueError, match="not a reproduction report"):
        report.load(bad)
    bad.write_text("{not json")
    with pytest.raises(ValueError, match=str(bad.name)):
        report.load(bad)


def test_report_is_not_a_paper():
    assert "report" not in reproduce.paper_names()


def _cited_tests() -> list[str]:
    cited = []
    for path in sorted((ROOT / "clsas" / "reproduce").glob("*.py")):
        cited += re.findall(r"test:(tests/test_\w+\.py::test_\w+)", path.read_text(encoding="utf-8"))
    return cited


def test_every_test_a_reason_cites_exists():
    cited = _cited_tests()
    assert cited, "the reproductions cite no test"
    for item in cited:
        file, name = item.split("::")
        tree = ast.parse((ROOT / file).read_text(encoding="utf-8"))
        names = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
        assert name in names, f"{item} is cited as evidence but does not exist"


def _validation_script():
    import importlib.util

    spec = importlib.util.spec_from_file_location("validation", ROOT / "bench" / "validation.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_validation_page_is_rendered_from_the_json(tmp_path):
    """bench/validation.py --render: the summary, each table with its verdict column, the
    reasons with their evidence, the experiments and the benches' figures, written atomically;
    a reproduction without JSON is listed as not in the common format."""
    validation = _validation_script()
    data = tmp_path / "data"
    data.mkdir()
    rep = _report()
    rep.paper = reproduce.paper_names()[0]
    report.write_json(rep, data / f"{rep.paper}.json")
    (data / "benches.jsonl").write_text(json.dumps({"bench": "ptrs", "backend": "opencl", "device": "cpu",
                                                    "size": {"rows": 4}, "rate": 1.5, "unit": "M/s",
                                                    "seconds": 0.2, "kernel": "x"}) + "\n")
    out = tmp_path / "validation.md"
    assert validation.main(["--render", "--data", str(data), "--out", str(out)]) == 0
    page = out.read_text()
    assert f"## {rep.paper}: a demo table" in page and "| T2 | PSLR (dB) | -14 | -11 | 3 | 0.5 | differs: window |" in page
    assert "differs: window" in page and "**window**: the paper weights the band Evidence: experiment:window" in page
    assert "### Experiment window" in page and "Finding: hamming gives the paper's figure" in page
    assert "| ptrs | opencl | 1.5 | M/s |" in page
    for other in reproduce.paper_names()[1:]:
        assert f"| {other} | not in the common format yet" in page or f"| {other} | no JSON in docs/validation/" in page \
            or f"## {other}" in page
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "validation.md"]


def test_validation_runs_each_reproduction_outside_the_checkout(tmp_path, monkeypatch):
    """bench/validation.py runs ``clsas reproduce PAPER --json`` in a temporary folder, so the
    figures a reproduction draws into its working folder by default (reproduce-PAPER/) land
    neither in the checkout nor in the page's data; the table goes to --data by an absolute path."""
    validation = _validation_script()
    calls = []

    def fake_clsas(*args, cwd=validation.ROOT, **kwargs):
        calls.append((args, Path(cwd)))
        if "--help" in args:
            return subprocess.CompletedProcess(args, 0, stdout="--json PATH", stderr="")
        figures = Path(cwd) / f"reproduce-{args[1]}"  # what a reproduction's default --out does
        figures.mkdir()
        (figures / "figure.png").write_bytes(b"png")
        Path(args[args.index("--json") + 1]).write_text("{}")
        return subprocess.CompletedProcess(args, 0)

    monkeypatch.setattr(validation, "_clsas", fake_clsas)
    paper = reproduce.paper_names()[0]
    data = tmp_path / "data"
    data.mkdir()
    monkeypatch.chdir(tmp_path)
    validation.run_papers([paper], Path("data"))  # a relative --data still names the same folder
    (_, help_cwd), (args, run_cwd) = calls
    assert args[:2] == ("reproduce", paper) and Path(args[args.index("--json") + 1]).is_absolute()
    assert run_cwd != validation.ROOT and not run_cwd.exists()  # a temporary folder, removed afterwards
    assert sorted(p.name for p in data.iterdir()) == [f"{paper}.json"]
