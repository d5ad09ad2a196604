"""The TOML scenario schema: which table holds which part of a Scenario, and its keys.

A table's keys are the fields of the dataclass it builds (:mod:`clsas.scene.scenario`,
:mod:`clsas.scene.targets`), with the same names, units and checks, so the schema follows
the classes: a field added to a class is written, read and checked without a change here
(``tests/test_scenario_toml.py`` fails if a field is not round-tripped). The exceptions are
the targets' ``kind`` (which class), the complex reflectivity of point targets (TOML has no
complex numbers: ``reflectivity`` holds the real parts, ``reflectivity_imag`` the imaginary
ones) and a mesh's source (``mesh`` a file path, or ``vertices`` and ``faces`` inline).
Full description with an example: docs/scenario-toml.md.
"""

from __future__ import annotations

import dataclasses

from ...scene.scenario import Array, Medium, Platform, PulseSchedule, Recording, Sonobuoy, Waveform
from ...scene.seafloor import Seafloor
from ...scene.surface import SeaSurface
from ...scene.targets import MeshTarget, PointTargets

SCHEMA_VERSION = 1

#: one table per part: TOML name -> class (recording, seafloor and surface are optional; the
#: seafloor's ``sediment`` is a name of clsas.scene.seafloor.SEDIMENTS or a [seafloor.sediment]
#: table of Sediment's fields)
TABLES = {"medium": Medium, "waveform": Waveform, "platform": Platform, "array": Array,
          "schedule": PulseSchedule, "recording": Recording, "seafloor": Seafloor, "surface": SeaSurface}
#: arrays of tables: TOML name -> class of each entry (targets: by their ``kind``)
ARRAYS_OF_TABLES = {"sonobuoys": Sonobuoy, "targets": None}
TARGET_KINDS = {"points": PointTargets, "mesh": MeshTarget}
#: keys a target table has beyond its class's fields
TARGET_EXTRA_KEYS = {"points": ("kind", "reflectivity_imag"),
                     "mesh": ("kind", "vertices", "faces", "process")}
TOP_KEYS = ("schema_version",) + tuple(TABLES) + tuple(ARRAYS_OF_TABLES)


def field_names(cls) -> tuple:
    return tuple(f.name for f in dataclasses.fields(cls))


def required_fields(cls) -> tuple:
    return tuple(f.name for f in dataclasses.fields(cls)
                 if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING)


def table_keys(cls, kind: str | None = None) -> tuple:
    """Every key a table building ``cls`` may hold."""
    return field_names(cls) + (TARGET_EXTRA_KEYS[kind] if kind else ())
