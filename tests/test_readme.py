"""The README's Python examples: every import they make exists (the examples themselves take
seconds to minutes each and are timed by hand, their cost stated beside them)."""

from __future__ import annotations

import ast
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


def _readme_commands(heading: str = "## The command line") -> list[list[str]]:
    """The ``clsas ...`` lines of the README's block under ``heading``, as argument lists (the
    comments dropped)."""
    block = re.search(re.escape(heading) + r"\n+```\n(.*?)```", README.read_text(), re.S).group(1)
    return [shlex.split(line.split("#")[0]) for line in block.splitlines() if line.startswith("clsas ")]


def test_the_readmes_command_line_block_is_found():
    commands = _readme_commands()
    assert len(commands) >= 5 and all(c[0] == "clsas" for c in commands)


@pytest.mark.slow
def test_the_readmes_command_line_runs_in_order_as_a_new_user_would(tmp_path):
    """Each command of "The command line", in the README's order, in an empty folder (with the
    repository's examples/ beside it): status 0. A fresh-clone trial found the fifth failing
    (`clsas plot img.nc` refusing to replace the img.png the third had written)."""
    (tmp_path / "examples").symlink_to(README.parent / "examples")
    env = dict(os.environ, TQDM_DISABLE="1")
    for args in _readme_commands():
        if args[1] == "bench":  # times the stages: minutes, and nothing it writes
            continue
        done = subprocess.run([sys.executable, "-m", "clsas", *args[1:]], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, (args, done.stderr[-500:])


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 5


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_example_imports_resolve(index):
    source = BLOCKS[index].replace("    ...\n", "    pass\n")
    imports = [node for node in ast.walk(ast.parse(source)) if isinstance(node, (ast.Import, ast.ImportFrom))]
    for node in imports:  # dask comes with the test extras
        exec(compile(ast.Module(body=[node], type_ignores=[]), f"README block {index}", "exec"), {})


# --- the examples run, as written (slow) --------------------------------------------------------

#: statements left out, by the text they start with (the README states their cost): the ones after
#: them in the same block that need what they make are left out too (a NameError is not a failure
#: there: see _run)
TOO_LONG = {
    "scene = presets.mine_scene()": "13 minutes: 358,387 facets simulated with bottom bounces",
    "echo = clsas.simulate(scene)": "the seafloor scenes: minutes to tens of minutes",
    "echo = clsas.simulate(scene, multipath=2": "a second-order multipath seafloor simulation",
    "compressed = clsas.simulate(scene, compressed=": "a seafloor simulation",
    "clsas.synthesis.delays(scene, path=": "the delays of a seafloor's facets",
    "image = clsas.backproject(clsas.range_compress(echo, window=\"hamming\", upsample=2)": "images the mine scene",
}

#: statements known to fail as the README writes them, with the error they raise (reported to the
#: section's owner): the test holds them to that error, so a fixed README fails here until the entry
#: goes, and what they would have made is left out as above
KNOWN_BROKEN: dict = {}

NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def _headings() -> list:
    """The section heading above each Python block."""
    text = README.read_text()
    out = []
    for match in re.finditer(r"```python\n", text):
        above = re.findall(r"^#+ (.+)$", text[:match.start()], re.M)
        out.append(above[-1] if above else "")
    return out


def _claims(comment: str) -> list[float]:
    """The numbers a comment states as the line's result: a comment that starts with a number
    (``# 0.0066``, ``# -33, -22, -19 dB``), or its part after the last colon does (``# Francois
    & Garrison 1982: 45.1 dB/km``); other comments claim nothing."""
    text = comment.rsplit(":", 1)[-1].strip()
    if not NUMBER.match(text):
        return []
    return [float(n) for n in NUMBER.findall(text.split("(")[0])]


def _agrees(got: float, claimed: float, text: str) -> bool:
    """Within 10 % of the claim, or within half a unit of its last printed digit."""
    decimals = len(text.split(".")[1]) if "." in text and "e" not in text else 0
    return abs(got - claimed) <= max(0.1 * abs(claimed), 0.5 * 10.0**-decimals)


def _run(source: str, namespace: dict, skipped: list) -> list:
    """Run the block's statements in ``namespace``, one at a time, leaving out those of
    TOO_LONG (and those that use what they would have made); returns (line, comment, value or
    printed text) of each expression statement and print call."""
    import contextlib
    import io as _io

    lines = source.splitlines()
    results, missing = [], set()
    for node in ast.parse(source).body:
        text = "\n".join(lines[node.lineno - 1:node.end_lineno])
        reason = next((why for start, why in TOO_LONG.items() if text.lstrip().startswith(start)), None)
        broken = next((error for start, error in KNOWN_BROKEN.items() if text.lstrip().startswith(start)), None)
        names = {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}
        if broken is not None:
            with pytest.raises(Exception, match=re.escape(broken)):  # still broken: see KNOWN_BROKEN
                exec(compile(ast.Module(body=[node], type_ignores=[]), "README", "exec"), namespace)
            reason = "known broken: " + broken
        if reason or names & missing:
            skipped.append((text.splitlines()[0][:60], reason or "uses what a left-out line makes"))
            missing |= {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
            continue
        comment = lines[node.end_lineno - 1].partition("#")[2]
        out = _io.StringIO()
        with contextlib.redirect_stdout(out):
            if isinstance(node, ast.Expr):
                value = eval(compile(ast.Expression(node.value), "README", "eval"), namespace)
            else:
                exec(compile(ast.Module(body=[node], type_ignores=[]), "README", "exec"), namespace)
                value = None
        if isinstance(node, ast.Expr):
            shown = out.getvalue() if value is None else np.asarray(value).ravel().tolist() \
                if isinstance(value, (np.ndarray, list, tuple, float, int, np.floating)) else None
            results.append((text, comment, shown))
    return results


@pytest.mark.slow
def test_readme_examples_run_and_print_what_they_claim(tmp_path, monkeypatch):
    """Every Python block of the README, in order, in one namespace (as a reader pastes them),
    in a fresh folder; each line whose comment states its result (a number) gives it."""
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    skipped: list = []
    checked = 0
    for heading, block in zip(_headings(), BLOCKS):
        source = block.replace("    ...\n", "    pass\n")
        try:
            results = _run(source, namespace, skipped)
        except Exception as err:  # noqa: BLE001 - named with its block
            raise AssertionError(f"README block under '{heading}' failed: {type(err).__name__}: {err}") from err
        for text, comment, shown in results:
            claims = _claims(comment)
            if not claims or shown is None:
                continue
            values = [float(n) for n in NUMBER.findall(shown)] if isinstance(shown, str) else \
                [float(v) for v in shown]
            texts = NUMBER.findall(comment.rsplit(":", 1)[-1].split("(")[0])
            assert len(values) == len(claims) and all(_agrees(v, c, t) for v, c, t in zip(values, claims, texts)), \
                f"under '{heading}': {text.strip()} gives {values}, the README says {comment.strip()}"
            checked += 1
    assert checked >= 2, (checked, skipped)
