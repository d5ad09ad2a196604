"""Kernel records: each structured dtype and the C struct declared from it have one layout on the
device (offsets and sizes measured by the device's compiler)."""

from __future__ import annotations

import numpy as np
import pytest

from clsas import cstruct, geometry
from clsas.image.backprojection import direct as backprojection
from clsas.synthesis.echo import synth

RECORDS = {"node_t": geometry.NODE, "echo_pulse_t": synth.PULSE, "echo_rx_t": synth.RECEIVER,
           "echo_params_t": synth.PARAMS, "tile_ref_t": backprojection.TILE_REF,
           "tile_params_t": backprojection.TILE_PARAMS, "bp_pulse_t": backprojection.PULSE,
           "bp_block_params_t": backprojection.BLOCK_PARAMS}


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_device_layout_matches_the_dtype(opencl_device, name):
    import pyopencl as cl

    dtype = RECORDS[name]
    measures = [f"sizeof({name})"] + [f"offsetof({name}, {field})" for field in dtype.names]
    source = cstruct.declare(name, dtype) + "#ifndef offsetof\n#define offsetof(t, f) __builtin_offsetof(t, f)\n#endif\n" \
        + "__kernel void layout(__global int *out) {\n" + "".join(
        f"    out[{k}] = (int)({m});\n" for k, m in enumerate(measures)) + "}\n"
    ctx, queue = opencl_device.context, opencl_device.queue
    out = np.zeros(len(measures), np.int32)
    buf = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, out.nbytes)
    cl.Program(ctx, source).build().layout(queue, (1,), None, buf)
    cl.enqueue_copy(queue, out, buf)
    assert out.tolist() == [dtype.itemsize] + [dtype.fields[f][1] for f in dtype.names]


def test_declaration_names_every_field_with_its_c_type():
    text = cstruct.declare("pair_t", cstruct.record_dtype([("a", "f8", 3), ("k", "i4")]))
    assert "#pragma OPENCL EXTENSION cl_khr_fp64 : enable" in text
    assert "    double a[3];\n    int k;\n} pair_t;" in text
    assert "pragma" not in cstruct.declare("f_t", cstruct.record_dtype([("x", "f4")]))


def test_unsupported_field_type_is_refused():
    with pytest.raises(ValueError, match="field 'flag'"):
        cstruct.record_dtype([("flag", "?")])
