"""Kernel records declared once: a NumPy structured dtype and the C struct the kernels read it as.

A record that the host fills and a kernel reads (a pulse's transmitter and emission time, a
launch's parameters, a tile's reference legs) is declared once, as a structured dtype; the
launcher fills it by field name and :func:`declare` gives the ``typedef struct`` that
:func:`clsas.opencl.program` puts in front of the kernel source (``preamble``), so no field is
known by its index on one side and by a swizzle on the other.

Fields are scalars (float32, float64, int32, uint32), fixed-size arrays of them (``("tx", "f8",
3)`` becomes ``double tx[3]``; a kernel reads it as a vector with ``vload3(0, rec.tx)``), or
records declared before them in the same :func:`declare_all` (``("parent", FRAME)`` becomes
``ffbp_frame_t parent`` when FRAME is declared as ``ffbp_frame_t``). With
``align=True`` NumPy lays such a dtype out as C does (each field at a multiple of its own size,
the record padded to a multiple of its largest field), which tests/test_cstruct.py checks
against the device's own ``offsetof`` and ``sizeof``.
"""

from __future__ import annotations

import numpy as np

_C_TYPES = {np.dtype(np.float32): "float", np.dtype(np.float64): "double", np.dtype(np.int32): "int",
            np.dtype(np.uint32): "uint"}


def record_dtype(fields) -> np.dtype:
    """A C-compatible structured dtype from ``[(name, type), (name, type, count), ...]`` (a type may
    be another record); ValueError for a field type a kernel struct cannot hold."""
    dtype = np.dtype(fields, align=True)
    for name in dtype.names:
        base = dtype.fields[name][0].base
        if base not in _C_TYPES and base.names is None:
            raise ValueError(f"field {name!r} has type {base}; kernel records take {sorted(map(str, _C_TYPES))} "
                             "or another record")
    return dtype


def declare(name: str, dtype: np.dtype, known: dict | None = None) -> str:
    """``typedef struct { ... } name;`` for a dtype made by :func:`record_dtype` (preceded by the
    fp64 pragma when a field is double); ``known`` maps the records its fields may be (dtype ->
    C name), as :func:`declare_all` gives them."""
    lines, doubles = [], False
    for field in dtype.names:
        sub = dtype.fields[field][0]
        if sub.base.names is not None:
            ctype = (known or {}).get(sub.base)
            if ctype is None:
                raise ValueError(f"field {field!r} of {name} is a record not declared before it")
        else:
            ctype = _C_TYPES[sub.base]
        doubles |= ctype == "double"
        count = int(np.prod(sub.shape)) if sub.shape else 0
        lines.append(f"    {ctype} {field}{f'[{count}]' if count else ''};")
    pragma = "#pragma OPENCL EXTENSION cl_khr_fp64 : enable\n" if doubles else ""
    return pragma + "typedef struct {\n" + "\n".join(lines) + f"\n}} {name};\n"


def declare_all(records: dict) -> str:
    """The declarations of ``{C name: dtype}``, in order (a record a field holds comes first): a
    kernel's preamble."""
    known, text = {}, []
    for name, dtype in records.items():
        text.append(declare(name, dtype, known))
        known[dtype] = name
    return "".join(text)
