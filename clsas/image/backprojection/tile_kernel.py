"""bp_tile, back-projection's float32 kernel, and :class:`TileKernel`, the one object that owns it.

A :class:`TileKernel` holds everything kernels/bp_tile.cl's bp_tile reads besides the
records and the grid: its options (the ``-D`` defines), its records (declared here once as
structured dtypes; :mod:`clsas.cstruct` puts them in front of the source as C structs), the
per-(tile, pulse) references and the parameters it is given, the layout of its pixel fields,
and its launch, and bp_fields, the kernel that writes those fields for a grid's tiles
(:mod:`.tiles`: the pixels grouped so that the float32 geometry relative to each tile's
reference point stays within the phase budget). Direct back-projection (:mod:`.launcher`) and the
first stage of factorised back-projection (:mod:`clsas.image.ffbp.leaves`) both use it.

Derivation (``precision="single"``: float32 geometry relative to a reference per (tile, pulse)).
Let the tile's reference point meet pulse p at t1_ref, at q_ref (exact, float64,
:func:`clsas.geometry.legs`), and its echo reach the receiver at T_ref = t1_ref + t2_ref, at
R_ref; let B = q_ref - tx (|B| = c t1_ref) and C = R_ref - q_ref (|C| = c t2_ref). A pixel of
the tile sits at delta from the reference point and moves with it at v, so it meets the pulse
at q = q_ref + delta + v s1 with s1 = t1 - t1_ref; c t1 = |q - tx| gives
|B + delta + v s1|^2 = c^2 (t1_ref + s1)^2, and subtracting |B|^2 = c^2 t1_ref^2:

    (c^2 - |v|^2) s1^2 + 2 b1 s1 - N1 = 0,  N1 = 2 B.delta + |delta|^2,  b1 = c^2 t1_ref - (B + delta).v,

whose root near 0 is s1 = N1 / (b1 + sqrt(b1^2 + (c^2 - |v|^2) N1)) (no cancellation: b1 ~ c |B|
> 0). The receiver moves linearly over the tile's delay span, R = R_ref + v_r (s1 + s2) with
s2 = t2 - t2_ref, so R - q = C + e + v_r s2 with e = (v_r - v) s1 - delta, and c t2 = |R - q|
gives likewise

    (c^2 - |v_r|^2) s2^2 + 2 b2 s2 - N2 = 0,  N2 = 2 C.e + |e|^2,  b2 = c^2 t2_ref - (C + e).v_r,

s2 = N2 / (b2 + sqrt(b2^2 + (c^2 - |v_r|^2) N2)). The delay is T_ref + s1 + s2 (docs/design.md's
exact non-stop-and-go delay; stop-and-go is the same with v = v_r = 0 and references at eta);
the sample index (T_ref - t0) fs + (s1 + s2) fs is K_ref + (frac_ref + (s1 + s2) fs) and the
carrier cycles f0 T_ref (reduced in double) + f0 (s1 + s2). Nothing of size |B| is subtracted
in float: every term carries a relative error of a few eps32 of a quantity of size |delta|
(N1, N2, s1, s2 ~ |delta| / c; B, C, b1, b2 enter as ratios), and f0 (s1 + s2) ~ 2 f0 |delta| / c
cycles is rounded once more; counting about ERROR_FACTOR = 8 roundings of |delta| / c of delay,
the phase error is below 2 pi f0 8 eps32 |delta| / c, kept below PHASE_BUDGET by the tile size
(:func:`.tiles.plan_tiles`; tests/test_backprojection.py measures it). The receiver's velocity
v_r is the secant of its track over T_ref +- SPAN_FACTOR |delta|_max / c (which contains every
pixel's delay); where the track departs from that line by more than NODE_TOLERANCE wavelengths
(motion errors: kinks at its nodes), :meth:`TileKernel.references` says so and the caller runs
that receiver's pulses on the exact double kernel instead (:mod:`.exact_kernel`). The records'
offset (their first sample, an integer) is taken off the reference's integer sample index
K_ref, so the fraction, hence the image, does not depend on the span prepared; k_frac also
carries BIAS samples (taken off K_ref) so that k_frac + s fs is positive and the kernel splits it
by truncation.

Leg 1 without a square root or a division (pixels at rest, |delta| <= RHO_MAX |B| for every pixel
of the tile). With b1 = c^2 t1_ref and a1 = c^2, s1 = N1 / (b1 + sqrt(b1^2 + a1 N1)) =
(N1 / (2 b1)) g(x) with x = a1 N1 / b1^2 and g(x) = 2 / (1 + sqrt(1 + x)); since
-2 |B| |delta| <= N1 - |delta|^2 <= 2 |B| |delta| and a1 / b1^2 = 1 / |B|^2, x lies in
[rho^2 - 2 rho, rho^2 + 2 rho] with rho = |delta| / |B| <= RHO_MAX = 0.15, inside [-0.3, 0.33],
where the degree-7 polynomial LEG_POLY (the Chebyshev interpolant of g, converted to powers)
departs from g by at most 2.1e-8 relative (tests/test_backprojection.py checks it), far below
the float32 roundings of the stable root. The host sets ``poly`` per (tile, pulse) where the bound
holds (kernels/bp_tile.cl keeps the stable root elsewhere).

The return leg of a monostatic sonar with exact delays (``legs="mono"``): the receiver is at the
transmitter T at emission and moves uniformly at v_r (two position nodes), the pixel D = q - T
away (at rest). With c t1 = |D| and c t2 = |v_r (t1 + t2) - D|, squaring and subtracting
c^2 t1^2 = |D|^2 gives c^2 (t2^2 - t1^2) = |v_r|^2 (t1 + t2)^2 - 2 (t1 + t2) v_r.D; dividing by
t1 + t2 > 0, t2 - t1 = 2 (|v_r|^2 t1 - v_r.D) / (c^2 - |v_r|^2) exactly. Relative to the
reference (D = B + delta, t1 = t1_ref + s1), s = s1 + s2 = alpha s1 - w.delta with
alpha = 2 c^2 / (c^2 - |v_r|^2) and w = 2 v_r / (c^2 - |v_r|^2): one leg and a dot product.
"""

from __future__ import annotations

import dataclasses
import functools
import threading

import numpy as np

from ... import opencl
from ...cstruct import declare_all, record_dtype
from ...geometry import legs, two_node_velocity, uniform_nodes
from ...interp import TAP_ROWS, kernel_taps
from .tiles import LANES, GridPlan, aperture_spans, tile_half_extent

ITEM_ROWS = 4  # rows of LANES pixels a work-item unless the caller's tiling has others (ffbp's leaves: 4)
PULSE_BLOCK = 64  # pulses a launch: the float sums' block (relative error below 64 x 6e-8)
NODE_TOLERANCE = 1 / 2000  # of a wavelength: a receiver's allowed departure from linear motion over a tile
SPAN_FACTOR = 2.5  # a tile's delay span is +-SPAN_FACTOR * half_extent / c around its reference
RHO_MAX = 0.15  # a tile's half extent over its reference's range below which leg 1 is a polynomial (LEG_POLY)
# g(x) = 2 / (1 + sqrt(1 + x)) on [-0.3, 0.33]: the degree-7 Chebyshev interpolant in powers of x
# (relative error 2.1e-8; the module docstring), coefficients of x^0 .. x^7
LEG_POLY = (9.9999998396e-01, -2.5000014978e-01, 1.2500532606e-01, -7.8112992048e-02, 5.4411638394e-02,
            -4.1183750927e-02, 3.6752282125e-02, -2.7302034149e-02)
LEG_POLY_DOMAIN = (-0.3, 0.33)


def _horner(name: str, coefficients) -> str:
    """A C macro ``name(x)`` evaluating the polynomial (float coefficients of x^0, x^1, ...) by Horner's rule."""
    body = f"{coefficients[-1]:.10e}f"
    for a in coefficients[-2::-1]:
        body = f"({a:.10e}f + (x) * {body})"
    return f"#define {name}(x) {body}\n"

# bp_tile's records: the reference of a (tile, pulse) for each way of computing the legs
# (:meth:`TileKernel.legs_for`), the launch's parameters, and a row of LANES pixels (the offsets
# from the tile's reference point, |delta|^2, and delta . v for moving pixels)
_REF = [("leg1", "f4", 3), ("b1", "f4"), ("k1", "f4"), ("k2", "f4"), ("poly", "i4"), ("k_ref", "i4"), ("k_frac", "f4"),
        ("cycles", "f4"), ("range1", "f4")]
TILE_REFS = {"same": record_dtype(_REF),
             "mono": record_dtype(_REF + [("w", "f4", 3), ("alpha", "f4"), ("w_run", "i4")]),
             "two": record_dtype(_REF + [("leg2", "f4", 3), ("b2", "f4"), ("v_rx", "f4", 3), ("a2", "f4")])}
TILE_PARAMS = record_dtype([("a1", "f4"), ("fs", "f4"), ("f0", "f4"), ("velocity", "f4", 3), ("half_sin", "f4"),
                            ("c", "f4")])
# bp_refs' inputs (the references computed on the device): a pulse of a receiver's fields, a row
# of doubles each (transmitter, emission time, the receiver at emission and its velocity, its window
# start t0, its records' first sample, and legs "mono"'s w, alpha and w_run), in kernels/bp_refs.cl's order,
# and the launch's parameters
REF_FIELDS = ("tx_x", "tx_y", "tx_z", "eta", "rx0_x", "rx0_y", "rx0_z", "v_rx_x", "v_rx_y", "v_rx_z", "t0", "offset",
              "w_x", "w_y", "w_z", "alpha", "w_run")
REF_LANES = 8  # references a bp_refs work-item computes side by side (kernels/bp_refs.cl's REF_LANES)
REF_PARAMS = record_dtype([("c", "f8"), ("f0", "f8"), ("fs", "f8"), ("velocity", "f8", 3), ("half_extent", "f8"),
                           ("rho_max", "f8"), ("bias", "i4")])
_OFFSETS = [("dx", "f4", LANES), ("dy", "f4", LANES), ("dz", "f4", LANES), ("dd", "f4", LANES)]
PIXELS = record_dtype(_OFFSETS)
MOVING_PIXELS = record_dtype(_OFFSETS + [("dv", "f4", LANES)])
LEG_DEFINES = {"same": "SAME_LEGS", "mono": "MONO", "two": None}


@functools.lru_cache(maxsize=None)
def _preambles(legs: str, moving: bool) -> tuple[str, str]:
    """The C text in front of kernels/bp_tile.cl and kernels/bp_fields.cl (the records of
    legs ``legs`` and of pixels at rest or ``moving``, LEG_POLY), and for bp_refs (that and its own
    records): made once a configuration, not in every call's TileKernel (the same strings, so the
    same programs)."""
    preamble = declare_all({"tile_ref_t": TILE_REFS[legs], "tile_params_t": TILE_PARAMS,
                            "bp_pixels_t": MOVING_PIXELS if moving else PIXELS}) + _horner("LEG_POLY", LEG_POLY)
    return preamble, preamble + declare_all({"bp_ref_params_t": REF_PARAMS})


def w_runs(w: np.ndarray) -> np.ndarray:
    """For each of P pulses' w ((P, 3), rounded to float32 as the references hold it): how many of
    the pulses that follow it have a w of the same bits (legs "mono"'s ``w_run``: bp_tile makes the
    rows' w . delta once for such a run of pulses)."""
    bits = np.ascontiguousarray(w, np.float32).view(np.uint32)
    index = np.arange(bits.shape[0])
    if not np.any(bits != bits[:1]):  # one run (a receiver at constant velocity)
        return index[::-1].copy()
    breaks = np.flatnonzero(np.any(bits[1:] != bits[:-1], axis=-1))  # the last pulse of each run but the last
    return np.append(breaks, bits.shape[0] - 1)[np.searchsorted(breaks, index)] - index


def _rx_nodes(echo, hs: np.ndarray, pulses) -> np.ndarray:
    """(G, P, N, 3) m: the position nodes of receivers ``hs`` for ``pulses`` (an index array, or a
    slice: then sliced first, a view, and only the receivers copied)."""
    return echo.rx_pos[:, pulses][hs] if isinstance(pulses, slice) else echo.rx_pos[hs[:, None], pulses]


def _at_emission(echo, hs: np.ndarray, pulses) -> np.ndarray:
    """(len(hs), len(pulses), 3) m: receivers ``hs`` at fast time 0 of each pulse (an index array
    or a slice), as ``echo.rx_position(h, 0)`` gives them (the same arithmetic), every receiver at once."""
    nodes, pos = echo.rx_tau[hs], _rx_nodes(echo, hs, pulses)  # (G, N), (G, P, N, 3)
    if nodes.shape[1] == 1:
        return pos[:, :, 0].copy()
    g = np.arange(hs.size)
    seg = np.clip(np.sum(nodes < 0.0, axis=1) - 1, 0, nodes.shape[1] - 2)  # searchsorted(nodes, 0) - 1
    w = ((0.0 - nodes[g, seg]) / (nodes[g, seg + 1] - nodes[g, seg]))[:, None, None]
    return pos[g, :, seg] * (1 - w) + pos[g, :, seg + 1] * w


class TileKernel:
    """bp_tile for one configuration: the interpolator ``interp`` ("linear" or "sinc8"), the full
    integration angle ``aperture`` (rad, or None), the pixels' ``velocity`` (m/s), ``stop_and_go``,
    ``row_shift`` (ffbp's first stage: each tile reads its own leaf's rows of the records),
    ``rows`` (of LANES pixels a work-item: the tiling's, :attr:`.tiles.Tiling.rows`), and ``legs``, how the kernel computes the return leg (:meth:`legs_for` chooses it for a receiver):

    - ``"two"``: both legs, for any receiver (the module docstring);
    - ``"same"``: stop-and-go with the receiver at the transmitter (a monostatic sonar): t2 = t1;
    - ``"mono"``: exact delays, pixels at rest, the receiver at the transmitter at emission and
      moving uniformly (two position nodes): the return leg in closed form from the outgoing one
      (the module docstring).

    A work-item is ``rows`` rows of LANES pixels of one tile (a tile's slots come in whole
    work-items); slot m = LANES (rows g + r) + lane of work-item g. ``ROWS`` is the default.
    """

    LANES, ROWS, PULSE_BLOCK = LANES, ITEM_ROWS, PULSE_BLOCK

    def __init__(self, interp: str, aperture: float | None = None, velocity=(0.0, 0.0, 0.0),
                 stop_and_go: bool = False, row_shift: bool = False, legs: str = "two", rows: int = ITEM_ROWS):
        if legs not in TILE_REFS:
            raise ValueError(f"legs must be one of {sorted(TILE_REFS)}, got {legs!r}")
        self.interp, self.aperture, self.stop_and_go = interp, aperture, bool(stop_and_go)
        self.velocity = np.asarray(velocity, dtype=np.float64)
        self.v_k = np.zeros(3) if stop_and_go else self.velocity  # the pixels' motion the legs see
        self.half_sin = 1.0 if aperture is None else float(np.sin(aperture / 2))
        self.moving = bool(np.any(self.v_k))
        if (legs == "same") != (legs == "same" and self.stop_and_go) or (legs == "mono" and (self.stop_and_go
                                                                                              or self.moving)):
            raise ValueError(f"legs={legs!r} needs {'stop-and-go' if legs == 'same' else 'exact delays and pixels at rest'}")
        self.legs, self.rows = legs, int(rows)
        self.reference_dtype = TILE_REFS[legs]
        self.pixels = MOVING_PIXELS if self.moving else PIXELS
        self.pulse_span = aperture is not None and not row_shift  # a tile sums only the pulses that can see it
        self.defines = {"INTERP_LINEAR" if interp == "linear" else "INTERP_SINC8": 1, "TAP_ROWS": TAP_ROWS,
                        "ROWS": self.rows, **({"APERTURE": 1} if aperture is not None else {}),
                        **({"MOVING": 1} if self.moving else {}), **({"ROW_SHIFT": 1} if row_shift else {}),
                        **({LEG_DEFINES[legs]: 1} if LEG_DEFINES[legs] else {}),
                        **({"PULSE_SPAN": 1} if self.pulse_span else {})}
        self.preamble, self.ref_preamble = _preambles(legs, self.moving)
        self.field_defines = {"ROWS": self.rows, **({"MOVING": 1} if self.moving else {})}
        self.ref_defines = {**({"MOVING": 1} if self.moving else {}),
                            **({"STOP_AND_GO": 1} if self.stop_and_go else {}),
                            **({LEG_DEFINES[legs]: 1} if LEG_DEFINES[legs] else {})}
        self._variants = {}  # for_receiver's other configurations, by legs
        self._launchers = {}  # launch's kernels: (SCATTER, BP_STORE, CARRY, queue id, thread) -> (queue, kernel)

    def legs_for(self, echo, h: int) -> str:
        """How bp_tile computes receiver h's return leg (see the class docstring): ``"same"`` when,
        with stop-and-go, the receiver sits at the transmitter at every emission (a monostatic
        sonar, to 1e-6 of a wavelength); ``"mono"`` when, with exact delays and pixels at rest, it
        does so and moves uniformly (two position nodes); else ``"two"``."""
        at_transmitter = echo.rx_tau[h][0] == 0 and bool(
            np.max(np.linalg.norm(echo.rx_pos[h][:, 0] - echo.tx_pos, axis=-1))
            <= 1e-6 * echo.waveform.wavelength(echo.medium))
        if at_transmitter and self.stop_and_go:
            return "same"
        if at_transmitter and not self.moving and echo.rx_tau[h].size == 2:
            return "mono"
        return "two"

    def for_receiver(self, echo, h: int) -> "TileKernel":
        """This configuration with receiver h's legs (:meth:`legs_for`)."""
        legs = self.legs_for(echo, h)
        if legs == self.legs:
            return self
        if legs not in self._variants:  # one object a configuration (its kernels looked up once)
            self._variants[legs] = TileKernel(self.interp, self.aperture, self.velocity, self.stop_and_go,
                                              "ROW_SHIFT" in self.defines, legs, self.rows)
        return self._variants[legs]

    @staticmethod
    def half_extent(f0: float, c: float) -> float:
        """The largest distance (m) of a pixel from its tile's reference point within the phase
        budget (:func:`.tiles.tile_half_extent`)."""
        return tile_half_extent(f0, c)

    def params(self, c: float, f0: float, fs: float) -> np.void:
        """The launch's parameters (TILE_PARAMS) for sound speed ``c``, carrier ``f0`` and the
        records' rate ``fs``."""
        params = np.zeros((), TILE_PARAMS)
        params["a1"], params["fs"], params["f0"] = c * c - self.v_k @ self.v_k, fs, f0
        params["velocity"], params["half_sin"], params["c"] = self.v_k, self.half_sin, c
        return params[()]

    def taps(self, ctx):
        """The interpolator's tap table as a device buffer."""
        import pyopencl as cl

        return cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=kernel_taps(self.interp))

    def references(self, echo, h: int, pulses: np.ndarray, centres: np.ndarray, fs: float, half_extent: float,
                   offset: int = 0) -> tuple[np.ndarray, bool]:
        """The references (T, P) (:attr:`reference_dtype`: :data:`TILE_REFS` of its legs) of the T tile ``centres`` ((T, 3), or (P, T, 3):
        each pulse's own) for receiver h of ``echo`` and the P ``pulses`` (the module docstring),
        and whether the receiver moves linearly within NODE_TOLERANCE of a wavelength over the
        tiles' delay spans (always for stop-and-go and for receivers with two nodes, whose motion
        is uniform; where it does not, the pulses belong on the exact kernel). ``offset``: the
        first sample of the records the kernel reads, counted at ``fs`` from the window start t0
        (taken off the integer part only)."""
        c, f0 = echo.medium.sound_speed, echo.waveform.f0
        t1, q, t2, r = legs(echo, h, pulses, centres, self.velocity, self.stop_and_go)
        big_t = t1 + t2
        b_vec = q - echo.tx_pos[pulses][:, None, :]
        c_vec = r - q
        v_r = np.zeros_like(c_vec)
        departure = 0.0
        if not self.stop_and_go and echo.rx_tau[h].size == 2:
            # uniform motion: the secant over any span is the receiver's velocity
            v_r[:] = two_node_velocity(echo, h, pulses)[:, None, :]
        elif not self.stop_and_go and echo.rx_tau[h].size > 2:
            # secant of the receiver over the delay span T_ref +- span; the kernel's line passes through R_ref
            span = SPAN_FACTOR * half_extent / c
            ends = echo.rx_position(h, big_t[..., None] + [-span, span], pulses=pulses)
            v_r = (ends[..., 1, :] - ends[..., 0, :]) / (2 * span)
            dtau, _ = uniform_nodes(echo, h)
            # the piecewise-linear track departs from the line most at its nodes or the span's ends
            steps = np.arange(int(np.ceil(2 * span / dtau)) + 2)
            times = np.clip((np.floor((big_t - span) / dtau)[..., None] + steps) * dtau,
                            (big_t - span)[..., None], (big_t + span)[..., None])
            line = r[..., None, :] + v_r[..., None, :] * (times - big_t[..., None])[..., None]
            departure = float(np.max(np.linalg.norm(echo.rx_position(h, times, pulses=pulses) - line, axis=-1)))
        k_ref = (big_t - echo.t0[h]) * fs
        k_int = np.clip(np.floor(k_ref), -2**30, 2**30)
        cycles = f0 * big_t
        bias = self.bias(half_extent, c, fs)
        ref = np.empty(big_t.shape, dtype=self.reference_dtype)
        ref["leg1"] = b_vec
        b1 = c * c * t1 - b_vec @ self.v_k
        ref["b1"] = b1
        ref["k1"], ref["k2"] = 0.5 / b1, (c * c - self.v_k @ self.v_k) / (b1 * b1)
        ref["poly"] = (not self.moving) & (half_extent <= RHO_MAX * c * t1)
        ref["k_ref"] = k_int - offset - bias
        ref["k_frac"] = np.clip(k_ref - k_int, 0.0, np.nextafter(np.float32(1), np.float32(0))) + bias
        ref["cycles"] = cycles - np.round(cycles)
        ref["range1"] = c * t1
        if self.legs == "mono":  # s = alpha s1 - w . delta (the module docstring)
            a2 = c * c - np.einsum("...i,...i->...", v_r, v_r)
            ref["w"] = 2 * v_r / a2[..., None]
            ref["alpha"] = 2 * c * c / a2
            for t in range(ref.shape[1]):  # the runs of each tile's pulses
                ref["w_run"][:, t] = w_runs(ref["w"][:, t])
        elif self.legs == "two":
            ref["leg2"] = c_vec
            ref["b2"] = c * c * t2 - np.einsum("...i,...i->...", c_vec, v_r)
            ref["v_rx"] = v_r
            ref["a2"] = c * c - np.einsum("...i,...i->...", v_r, v_r)
        linear = departure <= NODE_TOLERANCE * echo.waveform.wavelength(echo.medium)
        return np.ascontiguousarray(ref.T), linear

    @staticmethod
    def bias(half_extent: float, c: float, fs: float) -> int:
        """BIAS (samples) added to k_frac and taken off k_ref: at least the largest |s fs| of a
        pixel within ``half_extent`` of its reference (s within +-SPAN_FACTOR half_extent / c), so
        that k_frac + s fs is positive and the kernel's truncation is the floor."""
        return int(np.ceil(SPAN_FACTOR * half_extent * fs / c)) + 1

    def on_device(self, echo, h: int) -> bool:
        """Whether bp_refs computes receiver h's references (:meth:`references_on_device`): not for a
        receiver followed between more than two position nodes with exact delays."""
        return self.stop_and_go or echo.rx_tau[h].size <= 2

    def references_on_device(self, queue, echo, h, pulses: np.ndarray, centres, n_tiles: int, fs: float,
                             half_extent: float, offset=0, tile_first=None):
        """Enqueue bp_refs: the references of :meth:`references` (its NumPy twin) for the
        ``n_tiles`` tile ``centres`` (a device buffer of (T, 3) doubles) computed on the device, a
        buffer of (T, P) :attr:`reference_dtype` records; None where the host must compute them
        (a receiver with more than two position nodes and exact delays, :meth:`on_device`:
        :meth:`references` follows its track and checks its linearity). ``h`` and ``offset`` may
        be sequences (G receivers and their records' first samples, all with this object's legs):
        then the buffer holds (T, G, P) records, receiver after receiver for each tile.
        ``tile_first`` (T,) ints (one receiver ``h``; ffbp's first stage, many sub-apertures in one
        launch): tile t's references are of pulses ``pulses[tile_first[t] + j]`` for j < P, P =
        ``len(pulses) - max(tile_first)``: a (T, P) buffer, each tile's row what a call on its
        own pulses gives, bit for bit."""
        import pyopencl as cl

        hs, offsets = np.atleast_1d(h), np.broadcast_to(offset, np.shape(np.atleast_1d(h)))
        if tile_first is not None:
            tile_first = np.ascontiguousarray(tile_first, np.int32)
            if (hs.size != 1 or tile_first.shape != (n_tiles,) or tile_first.min(initial=0) < 0
                    or tile_first.max(initial=0) >= pulses.size):
                raise ValueError(f"references_on_device tile_first: needs one receiver and {n_tiles} first pulses "
                                 f"in [0, {pulses.size}), got {hs.size} receivers and {tile_first}")
        if not all(self.on_device(echo, int(k)) for k in hs):
            return None
        rt = opencl.runtime()
        # the pulses' fields a row each (REF_FIELDS), receiver after receiver, each over
        # ``pulses``; REF_LANES - 1 columns of padding for the last work-item's vector loads
        columns, c = hs.size * pulses.size, echo.medium.sound_speed
        pulse = np.zeros((len(REF_FIELDS), columns + REF_LANES), np.float64)
        rows = pulse[:, :columns].reshape(len(REF_FIELDS), hs.size, pulses.size)  # (field, receiver, pulse)
        pick = pulses  # a run of consecutive pulses (the usual job) as a slice: views, not copies
        if pulses.size > 1 and pulses[-1] - pulses[0] == pulses.size - 1 and np.all(np.diff(pulses) == 1):
            pick = slice(int(pulses[0]), int(pulses[-1]) + 1)
        rows[0:3] = echo.tx_pos[pick].T[:, None, :]
        rows[3] = echo.eta[pick]
        rows[4:7] = np.moveaxis(_at_emission(echo, hs, pick), -1, 0)
        if not self.stop_and_go and echo.rx_tau.shape[-1] == 2:
            nodes = _rx_nodes(echo, hs, pick)
            rows[7:10] = np.moveaxis(nodes[:, :, 1] - nodes[:, :, 0], -1, 0)
            rows[7:10] /= np.diff(echo.rx_tau[hs], axis=-1)  # two_node_velocity of every receiver ((G, 1) s)
            if self.legs == "mono":  # w and alpha of each pulse (the module docstring), as bp_refs made them
                x, y, z = rows[7:10]
                a2 = c * c - ((x * x + y * y) + z * z)
                rows[12:15] = 2.0 * rows[7:10] / a2
                rows[15] = 2.0 * c * c / a2
                for g in range(hs.size):  # each receiver's runs (its pulses are its tiles' rows' columns)
                    rows[16, g] = w_runs(rows[12:15, g].T)
        rows[10], rows[11] = np.asarray(echo.t0)[hs][:, None], np.asarray(offsets)[:, None]
        params = np.zeros((), REF_PARAMS)
        params["c"], params["f0"], params["fs"] = c, echo.waveform.f0, fs
        params["velocity"], params["half_extent"], params["rho_max"] = self.velocity, half_extent, RHO_MAX
        params["bias"] = self.bias(half_extent, c, fs)
        per_tile = columns if tile_first is None else pulses.size - int(tile_first.max(initial=0))
        n_chunks = -(-per_tile // REF_LANES)
        n_items = n_tiles * n_chunks
        n_refs = n_tiles * per_tile
        out = cl.Buffer(rt.context, cl.mem_flags.READ_WRITE, self.reference_dtype.itemsize * max(n_refs, 1))
        pulse_buf = cl.Buffer(rt.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=pulse)
        extra, defines = (), self.ref_defines
        if tile_first is not None:
            extra = (cl.Buffer(rt.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=tile_first),)
            defines = {**defines, "TILE_FIRST": 1}
        opencl.kernel("bp_refs", "bp_refs", preamble=self.ref_preamble, defines=defines)(
            queue, *opencl.work_groups(n_items), centres, pulse_buf, np.int32(pulse.shape[1]), params[()],
            np.int32(per_tile), np.int32(n_chunks), np.int32(n_items), out, *extra)
        return out

    def spans(self, ref: np.ndarray, half_extent: float, c: float, first: int) -> np.ndarray:
        """PULSE_SPAN's pulses [start, stop) each tile of the references ``ref`` (T, P) (pulses
        ``first`` .. ``first + P - 1``) can see within the aperture (:func:`aperture_spans`)."""
        return aperture_spans(ref["leg1"][..., 1], ref["range1"], self.half_sin, half_extent,
                              float(np.linalg.norm(self.v_k)), c, first)

    def fields(self, queue, *, positions, index, tile_of, centres, n_slots: int):
        """Enqueue bp_fields: bp_tile's pixel fields (a device buffer of n_slots / LANES
        :attr:`pixels` records) of the slots whose pixels are ``index`` (device int32, -1 for
        padding, which gets the tile's reference point) among ``positions`` (device double (M, 3),
        m), the work-items' tiles ``tile_of`` (device int32) and the tiles' reference points
        ``centres`` (device double (T, 3), m)."""
        import pyopencl as cl

        rt = opencl.runtime()
        fields = cl.Buffer(rt.context, cl.mem_flags.READ_WRITE, self.pixels.itemsize * (n_slots // LANES))
        rows = n_slots // LANES
        opencl.kernel("bp_fields", "bp_fields", preamble=self.preamble, defines=self.field_defines)(
            queue, *opencl.work_groups(rows), positions, index, tile_of, centres, *(np.float64(v) for v in self.v_k),
            np.int32(rows), fields)
        return fields

    def launch(self, queue, *, pixels, tile_of, refs, ref_stride: int, ref_first: int, records, n_samples: int, taps,
               params, p_first: int, p_count: int, image, index=None, row_shift=None, spans=None,
               store: bool = False, carry=None, carry_mode: int = 0):
        """Enqueue bp_tile over the work-items of ``tile_of`` (a device buffer of one int32 a
        work-item; ``pixels`` ROWS records a work-item): add pulses p_first .. p_first + p_count
        - 1 of the ``records`` (rows of ``n_samples`` samples) into the double ``image``: at each
        slot's pixel ``index`` (device int32 a slot, -1 for padding) when given, else at the slot;
        ``refs`` holds tile t's reference of pulse p at t * ref_stride + p - ref_first.
        ``row_shift`` (with row_shift=True) and ``spans`` (with an aperture) as in the kernel's
        comment. ``store`` (without ``index``): the launch's sums are stored into the slots instead
        of added (BP_STORE: the image need not be zeroed first; the same values as adding them to
        zeros). ``carry`` (a device buffer of 8 bytes a slot) and ``carry_mode`` (bits 1: start from
        it, 2: end in it; without ``store`` or ``index``): the launch's float sums continue those an
        earlier launch left in ``carry`` and/or are left there for the next instead of being added
        into ``image`` (CARRY: a block of pulses over several launches, bit-identical to one).
        Returns the event."""
        if store and index is not None:
            raise ValueError("bp_tile store=True: only without index (a scattered image is added into)")
        if carry is not None and (store or index is not None):
            raise ValueError("bp_tile carry: only without store and index")
        extra = (row_shift,) if "ROW_SHIFT" in self.defines else ()
        extra += (spans,) if self.pulse_span else ()
        extra += (carry, np.int32(carry_mode)) if carry is not None else ()
        n_items = tile_of.size // 4
        # opencl.kernel's lookup (the runtime, the options' key) once per variant, queue and thread
        key = (index is not None, bool(store), carry is not None, id(queue), threading.get_ident())
        held = self._launchers.get(key)
        if held is None or held[0] is not queue:  # (the queue is held: its id is not reused)
            defines = {**self.defines, **({"SCATTER": 1} if index is not None else {}),
                       **({"BP_STORE": 1} if store else {}), **({"CARRY": 1} if carry is not None else {})}
            held = self._launchers[key] = (queue, opencl.kernel("bp_tile", "bp_tile", preamble=self.preamble,
                                                                defines=defines))
        kern = held[1]
        return kern(queue, *opencl.work_groups(n_items), pixels, tile_of, refs, np.int32(ref_stride),
                    np.int32(ref_first), records, taps, params, np.int32(p_first), np.int32(p_count),
                    np.int32(n_samples), np.int32(n_items), image,
                    *((index,) if index is not None else ()), *extra)

