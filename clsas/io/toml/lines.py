"""Where a key sits in a TOML text: its line number, for error messages (tomllib gives none).

A line scanner for the TOML clsas writes and people type: ``[table]`` and ``[[array]]``
headers, ``key = value`` lines (values may span lines: brackets are counted outside strings).
Keys it cannot place (dotted keys, inline tables) fall back to their table's header line.
"""

from __future__ import annotations

import re

_HEADER = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.-]+)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"""^\s*(["']?)([A-Za-z0-9_-]+)\1\s*=""")
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"|\'[^\']*\'')


class KeyLines:
    """Line numbers (1-based) of the headers and keys of a TOML text."""

    def __init__(self, text: str):
        self._where = {}
        table, index, depth, counts = "", None, 0, {}
        for number, line in enumerate(text.splitlines(), 1):
            bare = _STRING.sub('""', line).split("#", 1)[0]
            if depth == 0:
                head = _HEADER.match(line)
                if head:
                    table = head.group(2)
                    if head.group(1) == "[[":
                        index = counts[table] = counts.get(table, -1) + 1
                    else:
                        index = None
                    self._where.setdefault((table, index, None), number)
                    continue
                key = _KEY.match(bare)
                if key:
                    self._where.setdefault((table, index, key.group(2)), number)
            depth = max(0, depth + bare.count("[") + bare.count("{") - bare.count("]") - bare.count("}"))

    def line(self, table: str, index: int | None = None, key: str | None = None) -> int | None:
        """The line of ``key`` in ``table`` (entry ``index`` of an array of tables), else of the
        table's header, else of the top-level key naming the table; None if none is found."""
        probes = [(table, index, key), (table, index, None), ("", None, table)]
        if not table and key:  # a top-level name: a key, a [table] or the first [[array]] entry
            probes += [(key, None, None), (key, 0, None)]
        for probe in probes:
            if probe in self._where:
                return self._where[probe]
        return None
