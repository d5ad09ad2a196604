"""The reproductions' inputs: a paper's name and the counts on their command lines are checked and
named before any work."""

import argparse

import pytest

from clsas import reproduce
from clsas.reproduce import report


@pytest.mark.parametrize("name", ["nosuch", "report", None, 3])
def test_paper_refuses_what_is_not_a_paper(name):
    with pytest.raises(ValueError, match=r"^paper: must be one of \('heremans2009'"):
        reproduce.paper(name)


def test_paper_returns_the_reproduction():
    assert reproduce.paper("wu2018").__name__ == "clsas.reproduce.wu2018"


@pytest.mark.parametrize("name, option, value, low", [("wu2018", "--seed", "-1", 0), ("wu2018", "--pulses", "0", 1),
                                                       ("heremans2009", "--seed", "x", 0),
                                                       ("huang2022", "--timing-pulses", "2.5", 1),
                                                       ("zhang2019", "--pulses", "-3", 1)])
def test_counts_on_the_command_line_are_named(name, option, value, low, capsys):
    parser = argparse.ArgumentParser(prog=f"clsas reproduce {name}")
    reproduce.paper(name).add_arguments(parser)
    with pytest.raises(SystemExit) as stop:
        parser.parse_args([option, value])
    assert stop.value.code == 2
    assert f"argument {option}: must be an integer >= {low}, got '{value}'" in capsys.readouterr().err


def test_count_accepts_its_range():
    assert report.count(0)("0") == 0 and report.count(1)("7") == 7


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "x"])
def test_kiang2022_snr_is_a_finite_number(value, capsys):
    parser = argparse.ArgumentParser(prog="clsas reproduce kiang2022")
    reproduce.paper("kiang2022").add_arguments(parser)
    with pytest.raises(SystemExit):
        parser.parse_args([f"--snr={value}"])
    assert f"argument --snr: must be a finite number, got '{value}'" in capsys.readouterr().err
    assert parser.parse_args(["--snr", "-15"]).snr == -15.0
