"""The two 2-D phase multiplies of numerical PTRS imaging (Zhang, Tan & Ying 2019, eqs. 12-14).

Both read a 1-D table of G(s) = tau(T(s)) - s T(s) (:mod:`clsas.image.ptrs.stationary`; cubic
Hermite interpolation with dG/ds = -T) and multiply data in place by exp(-j 2 pi cycles):

- :func:`decouple`, in the 2-D frequency domain (rows f_t, columns f_tau), with a difference
  table D = G_a - G_b of two ranges r_a, r_b (G_b = 0, r_b = 0 for the bulk step):

      cycles(f_t, f_tau) = -(f0 + f_tau) D(-f_t / (f0 + f_tau)) + f0 D(-f_t / f0) + 2 f_tau (r_a - r_b) / c

  which is phi_de(r_a) - phi_de(r_b) / (2 pi) of eqs. (10)-(13) (phi_de = Psi - phi_ac + 4 pi f_tau r / c):
  the bulk filter exp(-j phi_de(r_c)) of eq. (12) (the range matched filter conj(P) of eq. 12
  is already applied: the input is range-compressed) and the differential filter of eq. (13).
- :func:`compress_azimuth`, in the range-Doppler domain (rows f_t, columns at ranges r), with
  G tabulated at range nodes and interpolated linearly between them:

      cycles(f_t, r) = -f0 G(-f_t / f0; r)       (the conjugate of eq. 8's phase: eq. 14)

Phases are computed in float64 (the terms are ~1e5 cycles) and reduced modulo 2 pi before the
complex64 phasor (:func:`clsas.image.record.unit_phasor`).
"""

from __future__ import annotations

import numpy as np

from ..record import unit_phasor
from .stationary import hermite

ROW_BLOCK = 64  # rows a step (bounds the float64 temporaries)


def decouple(data: np.ndarray, ft: np.ndarray, ftau: np.ndarray, f0: float, table_g: np.ndarray,
             table_t: np.ndarray, s_first: float, ds: float, kappa: float) -> np.ndarray:
    """Multiply ``data`` (complex64 (len(ft), len(ftau)), in place) by exp(-j 2 pi cycles) with
    the difference tables ``table_g`` (D = G_a - G_b) and ``table_t`` (T_a - T_b, its slope
    -dD/ds) on slopes s_first + k ds, and ``kappa`` = 2 (r_a - r_b) / c (s). Returns ``data``."""
    row_term = f0 * hermite(table_g, table_t, s_first, ds, -ft / f0)
    for lo in range(0, ft.size, ROW_BLOCK):
        rows = slice(lo, lo + ROW_BLOCK)
        f = f0 + ftau[None, :]
        s = -ft[rows, None] / f
        cycles = -f * hermite(table_g, table_t, s_first, ds, s) + row_term[rows, None] + kappa * ftau[None, :]
        data[rows] *= unit_phasor(-2 * np.pi * cycles)
    return data


def compress_azimuth(data: np.ndarray, ft: np.ndarray, f0: float, node_g: np.ndarray, node_t: np.ndarray,
                     s_first: float, ds: float, column_node: np.ndarray, column_weight: np.ndarray) -> np.ndarray:
    """Multiply ``data`` (complex64 (len(ft), n_columns), in place) by exp(+j 2 pi f0 G(-f_t / f0; r))
    with G tabulated at range nodes (``node_g``, ``node_t``: (n_nodes, n_s)); column j reads
    nodes ``column_node[j]`` and ``column_node[j] + 1`` with weights 1 - w, w (w =
    ``column_weight[j]``). Returns ``data``."""
    at_nodes = f0 * hermite(node_g, node_t, s_first, ds, -ft / f0).T  # (n_ft, n_nodes), cycles
    for lo in range(0, ft.size, ROW_BLOCK):
        rows = slice(lo, lo + ROW_BLOCK)
        a = at_nodes[rows]
        cycles = a[:, column_node] * (1 - column_weight) + a[:, column_node + 1] * column_weight
        data[rows] *= unit_phasor(2 * np.pi * cycles)
    return data
