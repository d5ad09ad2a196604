"""Time-domain back-projection for any geometry: :func:`backproject`, the public call.

For every pixel P (its position at t = 0; with ``target_velocity`` v it moves, P(t) = P + v t,
which focuses a moving target, Kiang & Kiang 2022), every selected receiver h and pulse p:

    tau   = t1 + t2, the exact two-way delay: transmitter at its emission position T(eta),
            the pixel met at eta + t1 with c t1 = |P(eta + t1) - T(eta)|, the receiver at
            eta + t1 + t2 with c t2 = |R_h(eta + t1 + t2) - P(eta + t1)| (the receiver's
            positions come from EchoData: linear between its nodes);
            ``stop_and_go=True`` evaluates all positions at eta;
    image(P) += s_h,p(tau) exp(+j 2 pi f0 tau),

s the range-compressed record sampled at ``t0_h + k / fs``: its value at tau comes from linear
interpolation of the record upsampled by ``upsample`` (a 24-tap windowed-sinc FIR on the device, FFT
blocks for echoes sampled below 1.25 B: :mod:`clsas.image.upsample`; ``interp="linear"``;
:mod:`clsas.image.backprojection.records`: only the fast-time span the grid reaches) or from an
8-tap Kaiser-windowed sinc of :mod:`clsas.interp` on the original samples (``interp="sinc8"``;
:func:`clsas.interp.read_rows` in the reference, ``kernels/interp.h`` in the kernels). The
rotation exp(+j 2 pi f0 tau) undoes the carrier phase exp(-j 2 pi f0 tau) of the baseband echo
(docs/design.md signal model), so all contributions of a scatterer add in phase at its pixel.

Aperture: ``aperture`` (radians, full integration angle) keeps only the pulses that see the
pixel within +-aperture/2 of broadside: |sin theta| <= sin(aperture / 2) with sin theta the
along-track (y) component of the unit vector from the transmitter to the pixel.

Precision (OpenCL). ``precision="single"``: the geometry runs in float32 *relative to a
reference point per spatial tile and pulse* whose exact legs the host computes in float64
(derivation and error bound in :mod:`.tile_kernel`); the phase error this leaves is
below ``PHASE_BUDGET`` = 2e-3 rad by construction of the tiles (at any range: it scales with the
tile's size, not with the range), well inside the 0.01 rad budget at 2 km and 150 kHz. Where a
receiver's motion is not linear within lambda / 2000 over a tile's delay span (motion errors
with kinks between its position nodes) that receiver's pulse block falls back to the exact
double kernel (delays and carrier cycles in double per pixel). The interpolation, the phase
factor (fractional cycles, polynomial sin/cos, error < 1e-6) and the accumulation are float.
Sums are blocked: float over a block of at most ``PULSE_BLOCK`` = 64 pulses (relative error
below 64 x 6e-8 = 4e-6 even if every rounding adds up), then added into a double image, so
10^5 pulses x receivers add at most another 10^5 x 1.1e-16 relative. ``precision="double"``
runs the exact double kernel with the data path in double as well.

Where the work happens: :mod:`.records` (the range-compressed records, prepared once or per
call), :mod:`.tile_kernel` (bp_tile), :mod:`.tiles` (the grid's tile plan), :mod:`.reference` (the NumPy
reference), :mod:`.launcher` (the OpenCL launches of bp_tile and
:mod:`.exact_kernel`'s bp_block, and their memory). Fixed cost per call, and how to pay it once:
the records' upsampling and upload (:func:`.records.prepare`), the grid's tile plan
(:class:`.tiles.GridPlan`, which a call on a Grid also makes once and keeps while that Grid object
lives); the per-(tile, pulse) references depend on both and are computed in every call.
"""

from __future__ import annotations

import warnings
import weakref

import numpy as np

from ... import backend as _backend
from ... import budget, validate
from ...model import Grid, Image
from ...progress import NOMINAL_RATES, stage
from .launcher import backproject_opencl
from .records import record_bytes, records_for
from .reference import backproject_reference
from .tiles import GridPlan

__all__ = ["backproject"]

# what a call adds a pixel (tests/test_backprojection.py measures under 80 where no block is carried), and 8
# more for bp_tile's carry (one chunk's float sums, for records longer than records.LAUNCH_RECORD_BYTES a block);
# of these, a grid of one chunk's device inputs (its slots' pixel indices and fields, 20-24 bytes) stay with its
# plan after an OpenCL call (.tiles.GridPlan.kept; all plans' within .tiles.kept_limit), and a call that finds them
# there does not allocate them again
BYTES_PER_PIXEL = 88
# a Grid's tile plan, kept while the grid lives (12 bytes a pixel: the tiling's slot order and its
# inverse; after an OpenCL call on a grid of one chunk also its device inputs, 20-24 bytes a slot:
# GridPlan), so that calls on the same Grid tile it once, as a GridPlan passed in would
_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _plan_of(grid) -> GridPlan:
    """``grid``'s plan: a GridPlan as given, a Grid's the one kept for it (:data:`_PLANS`)."""
    if isinstance(grid, GridPlan):
        return grid
    plan = _PLANS.get(grid)
    if plan is None:
        plan = _PLANS[grid] = GridPlan(grid)
    return plan


def _check_call(grid, aperture, stop_and_go):
    if not isinstance(grid, (Grid, GridPlan)):
        raise TypeError(f"grid must be a clsas.model.Grid (Grid.plane, Grid.slant or Grid.points) or a GridPlan, got "
                        f"{type(grid).__name__}")
    if aperture is not None:
        validate.scalar("backproject aperture", aperture, low=0.0, high=np.pi, low_open=True, unit="rad",
                        why="the full integration angle")
    validate.flag("backproject stop_and_go", stop_and_go)
    size = grid.size if isinstance(grid, Grid) else grid.grid.size
    budget.check_bytes(f"backproject onto {size} pixels", BYTES_PER_PIXEL * float(size),
                       "image fewer pixels at a time (tiles of the grid)")


def _check_records(size: int, records, span: tuple[int, int], double: bool) -> None:
    """Refuse a call whose pixels and its records' buffers (:func:`.records.record_bytes`: the upsampled
    jobs' buffers, held records' staging or complex128 copies) exceed the memory budget, before either is
    allocated."""
    extra = record_bytes(records, span, double)
    if not extra:
        return
    if records.materialised:
        what = "and the held records' complex128 copies" if double else "and the held records' rows it stages"
        advice = "image fewer pixels at a time (tiles of the grid)"
    else:
        kind = "in complex128" if double else f"upsampled by {records.upsample}"
        what = (f"and its records {kind} a job at a time ({records.upload_pulses()} pulses x up to "
                f"{int(records.length.max())} samples)")
        advice = "image a smaller grid at a time (the records' span it reaches shrinks with it), or upsample less"
    budget.check_bytes(f"backproject onto {size} pixels {what}", BYTES_PER_PIXEL * float(size) + extra, advice)


def backproject(echo, grid, backend: str | None = None, receivers=None, interp: str | None = None,
                upsample: int | None = None, aperture: float | None = None, target_velocity=None,
                stop_and_go: bool = False, precision: str = "single", progress: bool = True,
                pulses=None) -> Image:
    """Back-project range-compressed echoes onto ``grid`` (see the module docstring).

    Parameters
    ----------
    echo : EchoData, range-compressed (:func:`clsas.range_compress`), or PreparedRecords
        (:func:`.records.prepare`): records prepared once for many calls; the image is bit-identical to
        the one the echo gives with the records' ``interp``, ``upsample`` and ``receivers``.
    grid : Grid (plane, slant plane or any 3-D points), or a :class:`.tiles.GridPlan` of one to image
        the same grid again without redoing its tile plan (a Grid's plan is also kept from its
        first call while the Grid object lives: 12 bytes a pixel, and 20-24 more of device inputs
        for a grid of one chunk on OpenCL, :class:`.tiles.GridPlan`).
    backend : {"numpy", "opencl", "auto"} or None.
    receivers : indices or names of the receivers to sum coherently (default: all; with prepared
        records: theirs, of which a subset may be chosen).
    interp : {"linear", "sinc8"}
        Linear interpolation of data upsampled by ``upsample`` (a 24-tap windowed-sinc FIR on the
        device, FFT blocks for echoes sampled below 1.25 B: :mod:`clsas.image.upsample`), or an
        8-tap windowed sinc on the original
        samples. Default "linear", or the prepared records' (which a different value contradicts).
    upsample : int in [1, 64], default 8 (or the prepared records'). A call on an echo upsamples
        only the fast-time span the grid reaches; to image many grids from one echo, prepare the
        records once with :func:`.records.prepare`.
    aperture : float, optional
        Full integration angle, radians.
    target_velocity : 3-vector, optional
        Velocity (m/s) of the pixels, to focus a target moving at it.
    stop_and_go : bool
        Use stop-and-go delays (all positions at the emission time).
    precision : {"single", "double"}
        The OpenCL kernel's data path (delays and carrier cycles are double either way).
    pulses : (start, stop), range or slice of consecutive pulses, optional
        Sum only pulses start .. stop - 1 (a sub-aperture, e.g. the first stage of a factorised
        back-projection: prepare the records once, image each sub-aperture on its own grid).
        Default: all.

    Returns
    -------
    Image with the grid's dims and axes, ``positions`` the grid's pixels, complex64; its
    provenance records the options and, for OpenCL, ``kernel_seconds`` (the back-projection kernels' own
    time: while some ran, kernels running side by side counted once).
    """
    _check_call(grid, aperture, stop_and_go)
    plan = _plan_of(grid)
    records, velocity, span, reached = records_for(echo, plan.grid, receivers, interp, upsample, target_velocity,
                                                   pulses, plan.box)
    double = _backend.check_precision(precision)
    _check_records(plan.grid.size, records, span, double)
    name = _backend.resolve(backend)
    g, source = plan.grid, records.echo
    work = g.size * len(records.receivers) * (span[1] - span[0])
    with stage(f"back-projection ({name}, {records.interp})", f"{g.size} pixels x {len(records.receivers)} receivers x "
               f"{span[1] - span[0]} pulses x {source.n_samples} samples", work,
               NOMINAL_RATES.get(("backprojection", name))):
        if name == "numpy":
            flat, fallbacks, kernel_seconds = backproject_reference(records, plan, aperture, velocity, stop_and_go,
                                                                    progress, span)
            seen = None
        else:  # seen: bp_order's checks of a grid of one chunk's image (bit 1: a pixel not zero, 2: not finite)
            flat, fallbacks, kernel_seconds, seen = backproject_opencl(records, plan, aperture, velocity, stop_and_go,
                                                                       progress, span, double, reached)
    with np.errstate(over="ignore"):  # a sum past complex64's range becomes inf: finite_result names the overflow
        flat = flat.astype(np.complex64, copy=False)  # launcher: complex64 already for a grid of one chunk
    if seen is None or seen & 2:  # (bp_order saw every pixel finite: no second pass over the image)
        validate.finite_result("backproject: the image", flat, "scale echo.data down", np.complex64)
    if not (np.any(flat) if seen is None else seen & 1) and any(np.any(source.data[h]) for h in records.receivers):
        warnings.warn("backproject: the image is all zeros: no pixel of the grid lies within the recorded fast-time "
                      "windows of the selected receivers (the swath); move the grid", validate.CoverageWarning,
                      stacklevel=2)
    return Image.on_grid(flat.reshape(g.shape), g,
                         {"algorithm": "backprojection", "backend": name, "precision": precision,
                          "interp": records.interp, "upsample": records.upsample,
                          "receivers": [source.receivers[h] for h in records.receivers],
                          "aperture": aperture, "target_velocity": velocity.tolist(),
                          "stop_and_go": bool(stop_and_go), "exact_fallback_blocks": fallbacks,
                          "prepared_records": records.materialised, "kernel_seconds": kernel_seconds,
                          "pulses": list(span),
                          "echo": dict(source.provenance)})
