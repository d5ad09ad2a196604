"""clsas reproduce heremans2009: every row has the chapter's value or bound and a verdict; the
seafloor's facet density does not change the DPCA results beyond their stated bounds."""

from __future__ import annotations

import json

import pytest

from clsas import cli


def test_rows_carry_the_chapters_values(monkeypatch):
    """The section 5.5 rows take Figs. 23-24's bounds (2 mm, ~0.1 mrad), the image rows compare
    with the motion-free image, eq. 47's widths are alpha_w c / 2B and alpha_w D / 2."""
    from clsas.reproduce import heremans2009, report

    rep = report.Report("heremans2009", "test")
    heremans2009._image_rows(rep, [("motion-free", -30.9, -24.5, 0.12, 8.6), ("uncompensated", 0.5, 10.7, 0.5, 9.3),
                                   ("compensated (eqs. 74-75)", -30.6, -24.3, 0.12, 8.6),
                                   ("along the DPCA track", -30.9, -24.2, 0.12, 8.6)])
    verdicts = {row.item: (row.paper, row.kind, row.verdict) for row in rep.rows}
    assert verdicts["centre point, uncompensated"] == (0.0, "at least", "match")
    assert verdicts["centre point, compensated (eqs. 74-75)"] == (0.0, "value", "match")
    assert verdicts["centre point, along the DPCA track"][1] == "value"
    assert [row.quantity for row in rep.rows] == ["azimuth PSLR re motion-free"] * 3
    assert heremans2009.PAPER_SWAY_MM == 2.0 and heremans2009.ALPHA_HAMMING == 1.30


@pytest.mark.slow
def test_reproduction_matches_the_chapter(tmp_path, capsys):
    """16 pings, no PGA cases: every row has a paper value (no 'clsas only') and matches (the
    report refuses a difference without a reason), the images measured against the true track."""
    out = tmp_path / "h.json"
    assert cli.main(["reproduce", "heremans2009", "--pings", "16", "--kiang-cases", "--out", str(tmp_path),
                     "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["counts"]["clsas only"] == 0
    rows = {(r["item"], r["quantity"]): r for r in doc["rows"]}
    assert doc["counts"]["differs"] == 0 and doc["counts"]["match"] == len(doc["rows"]) >= 12
    assert rows[("sway", "max error")]["clsas"] < 2.0 and rows[("yaw", "max error")]["clsas"] < 0.15
    assert ("centre point, compensated (eqs. 74-75)", "azimuth PSLR re true track") in rows
    assert any(item.startswith("omega-k") for item, _ in rows)
    assert "verdicts:" in capsys.readouterr().out
