"""Short text of arrays and provenance for the model's ``repr``s."""

from __future__ import annotations


def span(values, unit: str) -> str:
    """``"a..b unit"`` of a 1-D array (``"a unit"`` for one value)."""
    if values.size == 0:
        return "empty"
    if values.size == 1:
        return f"{values[0]:.6g} {unit}"
    return f"{values[0]:.6g}..{values[-1]:.6g} {unit}"


def provenance_line(provenance: dict) -> str:
    """The algorithm and the first keys of a provenance dict, on one line."""
    keys = list(provenance)
    head = provenance.get("algorithm", provenance.get("from", ""))
    shown = ", ".join(keys[:6]) + (", ..." if len(keys) > 6 else "")
    return f"{head} ({shown})" if head else f"({shown})"
