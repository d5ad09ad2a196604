"""The README's Python examples: every import they make exists (the examples themselves take
seconds to minutes each and are timed by hand, their cost stated beside them)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 5


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_example_imports_resolve(index):
    source = BLOCKS[index].replace("    ...\n", "    pass\n")
    imports = [node for node in ast.walk(ast.parse(source)) if isinstance(node, (ast.Import, ast.ImportFrom))]
    for node in imports:  # dask comes with the test extras
        exec(compile(ast.Module(body=[node], type_ignores=[]), f"README block {index}", "exec"), {})
