"""The version of clsas (ground floor: what files record as their writer)."""

__version__ = "0.1.0"
