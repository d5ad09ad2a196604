"""Kernel records: each structured dtype and the C struct declared from it have one layout on the
device (offsets and sizes measured by the device's compiler)."""

from __future__ import annotations

import numpy as np
import pytest

from clsas import cstruct, geometry
from clsas.image.backprojection import exact_kernel, tile_kernel
from clsas.image.ffbp import program
from clsas.synthesis.echo import records as echo_records

RECORDS = {"node_t": geometry.NODE, "echo_pulse_t": echo_records.PULSE, "echo_rx_t": echo_records.RECEIVER,
           "echo_params_t": echo_records.PARAMS, **{f"tile_ref_t ({legs})": ref for legs, ref in tile_kernel.TILE_REFS.items()},
           "tile_params_t": tile_kernel.TILE_PARAMS, "bp_pixels_t": tile_kernel.PIXELS,
           "bp_moving_pixels_t": tile_kernel.MOVING_PIXELS, "bp_pulse_t": exact_kernel.PULSE,
           "bp_block_params_t": exact_kernel.BLOCK_PARAMS, "bp_points_t": exact_kernel.POINTS,
           "ffbp_frame_t": program.FRAME, "ffbp_plane_t": program.PLANE, "ffbp_item_t": program.ITEM}


@pytest.mark.parametrize("name", sorted(RECORDS))
def test_device_layout_matches_the_dtype(opencl_device, name):
    import pyopencl as cl

    dtype = RECORDS[name]
    name = name.split(" ")[0]  # one C name, several layouts (bp_tile's references for each way of computing the legs)
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


def test_a_record_may_hold_a_record_declared_before_it(opencl_device):
    """A nested record (a field whose type is an earlier record of the same preamble) is declared
    by that record's C name, with the device's layout."""
    import pyopencl as cl

    inner = cstruct.record_dtype([("x", "f8", 3), ("n", "i4")])
    outer = cstruct.record_dtype([("k", "i4"), ("a", inner), ("b", inner), ("f", "f4")])
    text = cstruct.declare_all({"inner_t": inner, "outer_t": outer})
    assert "    inner_t a;" in text
    measures = ["sizeof(outer_t)", "offsetof(outer_t, a)", "offsetof(outer_t, b)", "offsetof(outer_t, f)"]
    source = text + "#ifndef offsetof\n#define offsetof(t, f) __builtin_offsetof(t, f)\n#endif\n" \
        + "__kernel void layout(__global int *out) {\n" + "".join(
        f"    out[{k}] = (int)({m});\n" for k, m in enumerate(measures)) + "}\n"
    out = np.zeros(len(measures), np.int32)
    buf = cl.Buffer(opencl_device.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
    cl.Program(opencl_device.context, source).build().layout(opencl_device.queue, (1,), None, buf)
    cl.enqueue_copy(opencl_device.queue, out, buf)
    assert out.tolist() == [outer.itemsize] + [outer.fields[f][1] for f in ("a", "b", "f")]
    with pytest.raises(ValueError, match="not declared before"):
        cstruct.declare("outer_t", outer)
