"""The two 2-D phase multiplies of numerical PTRS imaging (Zhang, Tan & Ying 2019, eqs. 12-14):
NumPy references and OpenCL launchers (kernels/ptrs.cl).

Both read a 1-D table of G(s) = tau(T(s)) - s T(s) (:mod:`clsas.image.ptrs.stationary`; cubic
Hermite interpolation with dG/ds = -T) and multiply complex64 data in place:

- :func:`decouple`, in the 2-D frequency domain (rows f_t, columns f_tau), by exp(-j 2 pi cycles)
  with a difference table D = G_a - G_b of two ranges r_a, r_b (G_b = 0, r_b = 0 for the bulk step):

      cycles(f_t, f_tau) = -(f0 + f_tau) D(-f_t / (f0 + f_tau)) + f0 D(-f_t / f0) + 2 f_tau (r_a - r_b) / c

  which is [phi_de(r_a) - phi_de(r_b)] / (2 pi) of eqs. (10)-(13) (phi_de = Psi - phi_ac + 4 pi f_tau r / c):
  the bulk filter exp(-j phi_de(r_c)) of eq. (12) (its range matched filter conj(P) is already
  applied: the input is range-compressed) and the differential filter of eq. (13).
- :func:`compress_azimuth`, in the range-Doppler domain (rows f_t, columns at ranges r), by
  exp(+j 2 pi f0 G(-f_t / f0; r)) (the conjugate of eq. 8's phase: eq. 14), with G tabulated at
  range nodes and interpolated linearly between them.

The references compute the phases in float64 (the terms are ~1e5 cycles) and reduce them modulo
one cycle before the phasor (:func:`clsas.image.record.unit_phasor`). The kernels work in float
only: the host splits every phase into a row term and a column term (reduced to a fraction of a
cycle in double) and a remainder of at most a few hundred cycles (the decoupling table less its
tangent at s = 0; the azimuth modulation's step from its range node), which float holds to
~2e-5 cycle, far inside the float32 phase budget of 0.01 rad (tests/test_ptrs.py holds the two
together).
"""

from __future__ import annotations

import numpy as np

from ... import backend as _backend
from ... import opencl
from ...kernelmath import unit_phasor
from .stationary import hermite

ROW_BLOCK = 64  # rows a reference step (bounds the float64 temporaries)
LANES = 16  # columns a work-item of the kernels


def _check_data(data: np.ndarray, rows: int, what: str) -> None:
    if not isinstance(data, np.ndarray) or data.dtype != np.complex64 or data.ndim != 2 \
            or not data.flags.c_contiguous or not data.flags.writeable or data.shape[0] != rows:
        raise ValueError(f"{what}: data must be a writeable C-contiguous complex64 array with {rows} rows, got "
                         f"{type(data).__name__} {getattr(data, 'shape', '')} {getattr(data, 'dtype', '')}")


def _decouple_args(data, ft, ftau, f0, table_g, table_t, s_first, ds):
    """Checked float64 arguments shared by both backends: (ft, ftau, row_term = f0 D(-f_t / f0))."""
    ft = np.ascontiguousarray(ft, dtype=np.float64)
    ftau = np.ascontiguousarray(ftau, dtype=np.float64)
    _check_data(data, ft.size, "decouple")
    if data.shape[1] != ftau.size:
        raise ValueError(f"decouple: data has {data.shape[1]} columns but ftau holds {ftau.size} frequencies")
    if table_g.shape != table_t.shape or table_g.ndim != 1 or table_g.size < 2:
        raise ValueError("decouple: table_g and table_t must be 1-D tables of one length >= 2")
    s_last = s_first + ds * (table_g.size - 1)
    f_low = f0 + ftau.min()
    if f_low <= 0 or np.abs(ft).max(initial=0.0) / f_low > min(-s_first, s_last) * (1 + 1e-12):
        raise ValueError(f"decouple: the slopes -f_t / (f0 + f_tau) reach {np.abs(ft).max() / f_low:.4g}, outside "
                         f"the table [{s_first:.4g}, {s_last:.4g}]")
    return ft, ftau, f0 * hermite(table_g, table_t, s_first, ds, -ft / f0)


def decouple_reference(data, ft, ftau, f0, table_g, table_t, s_first, ds, kappa, row_term) -> np.ndarray:
    """The NumPy reference of :func:`decouple` (float64 phases), in place."""
    for lo in range(0, ft.size, ROW_BLOCK):
        rows = slice(lo, lo + ROW_BLOCK)
        f = f0 + ftau[None, :]
        cycles = -f * hermite(table_g, table_t, s_first, ds, -ft[rows, None] / f) + row_term[rows, None] \
            + kappa * ftau[None, :]
        data[rows] *= unit_phasor(-2 * np.pi * cycles)
    return data


def _decouple_tables(ft, ftau, f0, table_g, table_t, s_first, ds, kappa, row_term):
    """The float32 arguments of the ptrs_decouple kernel (kernels/ptrs.cl): the table D less its
    tangent at s = 0, H = D - D0 - D1 s (a few hundred cycles of phase at most, so float holds
    it), and the row and column terms the tangent leaves, -(f0 + f_tau) (D0 + D1 s) =
    -(f0 + f_tau) D0 + f_t D1, reduced to a fraction of a cycle in double.

    Returns (inv_f, f, col: (n_cols,) each; row (n_rows, 2): -f_t / ds, row;
    table (n_s - 1, 4): H_k, ds H'_k, H_k+1, ds H'_k+1; b = -s_first / ds)."""
    d0, d1 = hermite(table_g, table_t, s_first, ds, 0.0, slope=True)
    slopes = s_first + ds * np.arange(table_g.size)
    h = table_g - d0 - d1 * slopes
    dh = ds * (-table_t - d1)
    table = np.stack([h[:-1], dh[:-1], h[1:], dh[1:]], axis=-1).astype(np.float32)
    f = f0 + ftau
    col = -f * d0 + kappa * ftau
    row = row_term + ft * d1
    rows = np.stack([-ft / ds, row - np.round(row)], axis=-1).astype(np.float32)
    return (1 / f).astype(np.float32), f.astype(np.float32), (col - np.round(col)).astype(np.float32), rows, table, \
        np.float32(-s_first / ds)


def decouple_opencl(data, ft, ftau, f0, table_g, table_t, s_first, ds, kappa, row_term) -> np.ndarray:
    """The ptrs_decouple launcher, in place."""
    *arrays, b = _decouple_tables(ft, ftau, f0, table_g, table_t, s_first, ds, kappa, row_term)
    _run("ptrs_decouple", data, arrays, [b, np.int32(table_g.size), np.int32(data.shape[1])])
    return data


def decouple(data: np.ndarray, ft, ftau, f0: float, table_g: np.ndarray, table_t: np.ndarray, s_first: float,
             ds: float, kappa: float, backend: str | None = None) -> np.ndarray:
    """Multiply ``data`` (complex64 (len(ft), len(ftau)), C-contiguous, in place) by
    exp(-j 2 pi cycles) (module docstring), with the difference tables ``table_g`` (D = G_a - G_b,
    s) and ``table_t`` (T_a - T_b, its slope -dD/ds, s) on slopes s_first + k ds, and ``kappa``
    = 2 (r_a - r_b) / c (s); ``ft``, ``ftau`` in Hz. Returns ``data``."""
    ft, ftau, row_term = _decouple_args(data, ft, ftau, f0, table_g, table_t, s_first, ds)
    run = decouple_reference if _backend.resolve(backend) == "numpy" else decouple_opencl
    return run(data, ft, ftau, f0, table_g, table_t, s_first, ds, kappa, row_term)


def _azimuth_args(data, ft, f0, node_g, node_t, s_first, ds, column_node, column_weight):
    ft = np.ascontiguousarray(ft, dtype=np.float64)
    _check_data(data, ft.size, "compress_azimuth")
    column_node = np.ascontiguousarray(column_node, dtype=np.int32)
    column_weight = np.ascontiguousarray(column_weight, dtype=np.float64)
    if column_node.shape != (data.shape[1],) or column_weight.shape != column_node.shape:
        raise ValueError(f"compress_azimuth: column_node and column_weight need one entry per column ({data.shape[1]})")
    if column_node.min(initial=0) < 0 or column_node.max(initial=0) > node_g.shape[0] - 2 \
            or np.any(np.diff(column_node) < 0):
        raise ValueError(f"compress_azimuth: column_node must be non-decreasing in [0, {node_g.shape[0] - 2}]")
    at_nodes = np.ascontiguousarray(f0 * hermite(node_g, node_t, s_first, ds, -ft / f0).T)  # (n_ft, n_nodes) cycles
    return column_node, column_weight, at_nodes


def compress_azimuth_reference(data, column_node, column_weight, at_nodes) -> np.ndarray:
    """The NumPy reference of :func:`compress_azimuth`, in place."""
    for lo in range(0, data.shape[0], ROW_BLOCK):
        a = at_nodes[lo:lo + ROW_BLOCK]
        cycles = a[:, column_node] * (1 - column_weight) + a[:, column_node + 1] * column_weight
        data[lo:lo + ROW_BLOCK] *= unit_phasor(2 * np.pi * cycles)
    return data


def compress_azimuth_opencl(data, column_node, column_weight, at_nodes) -> np.ndarray:
    """The ptrs_compress_azimuth launcher, in place: per (row, node) the float32 pair
    (A mod 1, A_next - A) (A ~ 1e5 cycles in double; the step between nodes ~ 1e2)."""
    steps = np.zeros_like(at_nodes)
    steps[:, :-1] = np.diff(at_nodes, axis=1)
    nodes = np.stack([at_nodes - np.round(at_nodes), steps], axis=-1).astype(np.float32)
    _run("ptrs_compress_azimuth", data, [nodes, column_node, column_weight.astype(np.float32)],
         [np.int32(at_nodes.shape[1]), np.int32(data.shape[1])])
    return data


def compress_azimuth(data: np.ndarray, ft, f0: float, node_g: np.ndarray, node_t: np.ndarray, s_first: float,
                     ds: float, column_node, column_weight, backend: str | None = None) -> np.ndarray:
    """Multiply ``data`` (complex64 (len(ft), n_columns), C-contiguous, in place) by
    exp(+j 2 pi f0 G(-f_t / f0; r)) with G tabulated at range nodes (``node_g``, ``node_t``:
    (n_nodes, n_s)); column j reads nodes ``column_node[j]`` and ``column_node[j] + 1`` with
    weights 1 - w, w (w = ``column_weight[j]``). Returns ``data``."""
    args = _azimuth_args(data, ft, f0, node_g, node_t, s_first, ds, column_node, column_weight)
    run = compress_azimuth_reference if _backend.resolve(backend) == "numpy" else compress_azimuth_opencl
    return run(data, *args)


def _run(kernel_name: str, data: np.ndarray, arrays: list, scalars: list) -> None:
    """Run ``kernel_name`` of kernels/ptrs.cl over every element of ``data`` (in place: the host
    array is the buffer, mapped back after the kernel), read-only ``arrays`` before ``scalars``:
    a work-item per row and 16 columns, in fixed work-groups (:func:`clsas.opencl.work_groups_2d`:
    PoCL then compiles each kernel once a process, whatever the data's shape)."""
    import pyopencl as cl

    rt = opencl.runtime()
    mf = cl.mem_flags
    knl = opencl.kernel("ptrs", kernel_name)
    buf = cl.Buffer(rt.context, mf.READ_WRITE | mf.USE_HOST_PTR, hostbuf=data)
    inputs = [cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a)) for a in arrays]
    knl(rt.queue, *opencl.work_groups_2d(data.shape[0], -(-data.shape[1] // LANES)), buf, *inputs, *scalars)
    mapped, _ = cl.enqueue_map_buffer(rt.queue, buf, cl.map_flags.READ, 0, data.shape, data.dtype)
    mapped.base.release()
