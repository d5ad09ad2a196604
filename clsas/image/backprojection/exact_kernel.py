"""bp_block, back-projection's exact double kernel, and :class:`ExactKernel`, the object that owns it.

bp_block (kernels/bp_block.cl) computes every pixel's exact delay in double per pulse
(kernels/geometry.h: the meeting time in closed form, the receiver followed between its
position nodes): ``precision="double"`` (data, phases and sums in double too), and the fallback
of ``precision="single"`` for a receiver whose motion is not linear over a tile's delay span
(:mod:`.tile_kernel`). An :class:`ExactKernel` holds its options, records (declared here once),
pulse and node buffers and parameters for one receiver and a run of pulses, and launches it.
"""

from __future__ import annotations

import numpy as np

from ... import opencl
from ...cstruct import declare_all, record_dtype
from ...geometry import NODE, uniform_nodes
from ...interp import TAP_ROWS

LANES = 8  # pixels a work-item (double8)
# bp_block's records: a pulse (transmitter, emission time, window start in samples, the records'
# first sample), the launch's parameters, and a work-item's LANES pixels at t = 0
PULSE = record_dtype([("tx", "f8", 3), ("eta", "f8"), ("t0_fs", "f8"), ("first", "i4")])
BLOCK_PARAMS = record_dtype([("c", "f8"), ("f0", "f8"), ("fs", "f8"), ("dtau", "f8"), ("velocity", "f8", 3),
                             ("half_sin", "f8")])
POINTS = record_dtype([("x", "f8", LANES), ("y", "f8", LANES), ("z", "f8", LANES)])
PREAMBLE = declare_all({"node_t": NODE, "bp_pulse_t": PULSE, "bp_block_params_t": BLOCK_PARAMS, "bp_points_t": POINTS})


class ExactKernel:
    """bp_block for the (M, 3) ``pixels`` (m at t = 0, M a multiple of LANES), receiver h of
    ``echo`` and the consecutive ``pulses`` (the buffers are indexed from ``pulses[0]``, like the
    records buffer the launch reads): records at rate ``fs`` whose first sample is ``offset``
    samples into the window, pixels moving at ``velocity``, ``interp``, ``aperture`` (rad or
    None), ``stop_and_go``, ``double`` (precision="double")."""

    def __init__(self, ctx, pixels: np.ndarray, echo, h: int, pulses: np.ndarray, fs: float, offset: int,
                 velocity: np.ndarray, interp: str, aperture: float | None, stop_and_go: bool, double: bool):
        import pyopencl as cl

        points = np.empty(pixels.shape[0] // LANES, POINTS)
        for k, name in enumerate(("x", "y", "z")):
            points[name] = pixels[:, k].reshape(-1, LANES)
        dtau, pos = uniform_nodes(echo, h)
        n_nodes = pos.shape[1]
        self.double = double
        self.defines = {"INTERP_LINEAR" if interp == "linear" else "INTERP_SINC8": 1, "TAP_ROWS": TAP_ROWS,
                        "N_NODES": n_nodes, "SEGMENT_PASSES": 1 if n_nodes == 2 else 3,
                        **({"APERTURE": 1} if aperture is not None else {}), **({"STOP_AND_GO": 1} if stop_and_go else {})}
        pulse = np.zeros(pulses.size, PULSE)
        pulse["tx"], pulse["eta"], pulse["t0_fs"] = echo.tx_pos[pulses], echo.eta[pulses], echo.t0[h] * fs
        pulse["first"] = offset
        nodes = np.zeros((pulses.size, n_nodes), NODE)
        nodes["pos"] = pos[pulses]
        self.points, self.pulse, self.nodes = (
            cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=a) for a in (points, pulse, nodes))
        params = np.zeros((), BLOCK_PARAMS)
        params["c"], params["f0"], params["fs"], params["dtau"] = echo.medium.sound_speed, echo.waveform.f0, fs, dtau
        params["velocity"] = velocity
        params["half_sin"] = 1.0 if aperture is None else np.sin(aperture / 2)
        self.params = params[()]

    def launch(self, queue, *, records, n_samples: int, taps, p_first: int, p_count: int, image, index=None):
        """Enqueue bp_block (one work-item a LANES pixels): add pulses p_first .. p_first + p_count
        - 1 (counted from the buffers' first pulse) of the ``records`` (rows of ``n_samples``) into
        the double ``image``: at pixel ``index[m]`` of pixel m (device int32, -1: dropped) when
        given, else at m. Returns the event."""
        defines = {**self.defines, **({"SCATTER": 1} if index is not None else {})}
        kern = opencl.kernel("bp_block", "bp_block", double=self.double, preamble=PREAMBLE, defines=defines)
        n_items = self.points.size // POINTS.itemsize
        return kern(queue, *opencl.work_groups(n_items), self.points, self.pulse, self.nodes, records, taps,
                    self.params, np.int32(p_first), np.int32(p_count), np.int32(n_samples), np.int32(n_items), image,
                    *((index,) if index is not None else ()))
