"""The moving target focused at every receiver that can focus it, on the r-y plane (issue 26,
deliverable 2; Kiang & Kiang 2022 section VI for the plane).

``method="bp"`` (default): time-domain back-projection in the target's frame. Every pixel is a
point of the target moving with the estimated velocity (:func:`clsas.backproject` with
``target_velocity``: the exact non-stop-and-go delay from the transmitter to the moving pixel
and on to the receiver, for every pulse), so every scatterer of the target is focused with its
own delay history, not only the reference point. The paper's chain (``method="paper"``) takes the
reference point's history (RCMC, RWC and azimuth compression with its K_a,eq and f_dc,eq, and
the model's higher-order terms) for the whole image: a scatterer elsewhere on the target has a
different history, and over long apertures the difference defocuses it (points 5 m from the
reference and a hull's ends: tests/test_moving_focus.py).

The pixels. The plane holds the transmitter's track (the y axis through it at eta_ref) and the
target's reference point q = p + v eta_ref; a pixel (r, y) is the point of that plane at
along-track y whose slant range from the transmitter at eta_ref is r,

    P(r, y) = T + (y - T_y) y^ + sqrt(r^2 - (y - T_y)^2) n^,      n^ = the unit normal from the
                                                                   track towards q,

the r and y of the scan image of :func:`clsas.synthesis.occlusion.scan_image` (viewed from A)
and of the paper chain's mapping (:mod:`.mapping`), so that the images of every receiver and
method share one plane. The pixel moves as P + v (t - eta_ref).

Autofocus (``sharpen``). A velocity error of 0.1 % leaves tens of radians of phase over 80 s
(:mod:`.sharpen`), the same for every scatterer of the target to first order (the error's phase
depends on the position only through the range, a relative change of size / range). So the
residual phase (p2, p3, p4, cycles at the aperture's ends) is found by sharpness on the
reference point's own range cells (:data:`AUTOFOCUS_CELLS` each side of its delay at eta_ref,
after aligning the record with the model: :func:`.azimuth.sharpened_bins`), where every scatterer
has the reference point's range and so its FM rate; across the whole target the rate varies as
1 / range (1 m of range at 2 km changes a quadratic phase of 25 rad by 0.3 %, which a hull's
extent in range would put into a common estimate). The record is then advanced by that delay
error phi / f0 and its phase rotated by phi before the back-projection.

The wrapped band. With intra-pulse Doppler at F_r = B the echo's band edge wraps round the
sampling rate and compresses T away in range (:func:`.records.wrapped_band`); that band is
zeroed in each receiver's record first, as the chain does, or the image holds its ghost.

Range-Doppler coupling. With intra-pulse Doppler each compressed peak lies f_dc(eta) / K_r after
the delay at the pulse's centre that the back-projection computes (:mod:`.layout`; three range
cells in Table II cases 6 and 8): the record is advanced by the reference point's
f_dc(eta) range_doppler first (the target's scatterers differ from it by a few Hz, a few ns).
"""

from __future__ import annotations

import logging

import numpy as np

from ... import budget, validate
from ...image.backprojection import backproject
from ...model import EchoData, Grid, Image
from . import filters
from .azimuth import sharpened_bins
from .records import compressed_receiver, records_of, without_wrapped_band
from .receiver_focus import focus_receiver
from .closedforms import Predicted, delay_history, delay_terms, higher_order_delay
from .layout import Layout
from .mapping import along_track_speed, to_ry
from .motion import MotionEstimate, check_echo, target_extent
from .sharpen import polynomial_phase

log = logging.getLogger("clsas")

METHODS = ("bp", "paper")
#: Range cells (1 / B) each side of the reference point's delay that the autofocus reads.
AUTOFOCUS_CELLS = 3
#: The default image: the target's size (from the chain's extents) times this, plus :data:`MARGIN_M`.
SIZE_FACTOR = 1.5
#: The default image's margin around the target, m (each side), and its least half-size, m.
MARGIN_M = 1.5
MIN_HALF_M = 3.0
#: Bytes a "bp" pixel holds while the grid is built (its positions and ~3 temporaries of
#: (n_y, n_r, 3) float64: :func:`ry_grid`), and per receiver (its complex64 image and the
#: back-projection's float64 accumulators).
GRID_PIXEL_BYTES = 96
IMAGE_PIXEL_BYTES = 24


def ry_grid(layout: Layout, position, velocity, r, y) -> Grid:
    """The pixels of the r-y plane (module docstring) on the axes ``r`` and ``y`` (m, 1-D), at
    slow time 0 (for :func:`clsas.backproject` with ``target_velocity=velocity``): dims ("y", "r")."""
    r = validate.array("ry_grid r", r, (-1,), bound=validate.MAX_COORDINATE)
    y = validate.array("ry_grid y", y, (-1,), bound=validate.MAX_COORDINATE)
    position = np.asarray(position, dtype=np.float64)
    velocity = np.asarray(velocity, dtype=np.float64)
    tx = layout.tx_position
    q = position + velocity * layout.eta_ref
    along = np.array([0.0, 1.0, 0.0])
    d = q - tx
    normal = d - d[1] * along
    if np.linalg.norm(normal) == 0:
        raise ValueError("the target is on the transmitter's track: no r-y plane")
    normal /= np.linalg.norm(normal)
    dy = y[:, None] - tx[1]
    cross = r[None, :] ** 2 - dy**2
    if np.any(cross <= 0):
        raise ValueError("ry_grid: every pixel needs r > |y - y_tx| (a slant range beyond its along-track offset)")
    pos = tx + dy[..., None] * along + np.sqrt(cross)[..., None] * normal - velocity * layout.eta_ref
    return Grid(pos, ("y", "r"), {"y": y, "r": r})


def residual_phase(comp: EchoData, layout: Layout, name: str, position, velocity) -> tuple[np.ndarray, np.ndarray]:
    """(phi (n_pulses,) cycles, (p2, p3, p4)): the phase the model at ``position``, ``velocity``
    leaves on the reference point's range cells of ``comp`` (one receiver, range-compressed), by
    sharpness (module docstring)."""
    rec = records_of(comp)
    tau_c, f_dc, k = delay_terms(layout, name, position, velocity)
    centre = (float(tau_c + layout.range_doppler * f_dc) - rec.t0) * rec.fs  # where the compressed peak is
    half = AUTOFOCUS_CELLS * rec.fs / rec.bandwidth
    n = rec.x.shape[1]
    bins = slice(int(np.clip(np.floor(centre - half), 0, n - 1)), int(np.clip(np.ceil(centre + half) + 1, 1, n)))
    higher = higher_order_delay(layout, name, position, velocity, rec.eta)
    _, _, p = sharpened_bins(rec, float(k), float(f_dc), bins, higher)
    return polynomial_phase(rec.eta, rec.eta_ref, p), np.asarray(p, dtype=np.float64)


def doppler_history(layout: Layout, name: str, position, velocity, eta) -> np.ndarray:
    """f_dc(eta) = f0 d tau / d eta (Hz, the shape of ``eta``) of the model's delay history at
    ``name`` (:func:`.closedforms.delay_history`), by central differences."""
    eta = np.asarray(eta, dtype=np.float64)
    step = 1e-3
    ahead = delay_history(layout, name, position, velocity, eta + step)
    behind = delay_history(layout, name, position, velocity, eta - step)
    return layout.f0 * (ahead - behind) / (2 * step)


def _axes(est: MotionEstimate, half_size, spacing, tau_span):
    layout = est.layout
    q = est.position + est.velocity * layout.eta_ref
    r_c = float(np.linalg.norm(q - layout.tx_position))
    if spacing is None:  # half the finer resolution cell, in range or along the track
        cells = [0.5 * layout.sound_speed / layout.bandwidth]
        for name in est.receivers:
            if name not in est.cannot_focus:
                k = abs(float(delay_terms(layout, name, est.position, est.velocity)[2]))
                cells.append(0.886 * abs(along_track_speed(layout, name, est.position, est.velocity))
                             / (k * layout.aperture))
        spacing = 0.5 * min(cells)
    spacing = validate.positive("focus_moving spacing", spacing, high=100.0, unit="m")
    if half_size is None:
        size = target_extent(layout, est.receivers, est.position, est.velocity)[0]
        half = max(MIN_HALF_M, 0.5 * SIZE_FACTOR * size + MARGIN_M)
        half_r = half_y = half
    else:
        values = np.atleast_1d(np.asarray(half_size, dtype=object))
        if values.size not in (1, 2):
            raise TypeError(f"focus_moving half_size: must be a number or (range, along-track) in m, got {half_size!r}")
        half_r = validate.positive("focus_moving half_size", values[0], high=1e4, unit="m")
        half_y = validate.positive("focus_moving half_size", values[-1], high=1e4, unit="m")
    if tau_span is not None:
        half_r = 0.25 * layout.sound_speed * tau_span
    n_r, n_y = int(np.ceil(half_r / spacing)), int(np.ceil(half_y / spacing))
    pixels = float(2 * n_r + 1) * float(2 * n_y + 1)
    receivers = len(est.receivers) - len(est.cannot_focus)
    budget.check_bytes(f"focus_moving's image of {2 * n_y + 1} x {2 * n_r + 1} pixels (half_size {half_r:g} x "
                       f"{half_y:g} m, spacing {spacing:g} m) at {receivers} receiver(s)",
                       pixels * (GRID_PIXEL_BYTES + IMAGE_PIXEL_BYTES * receivers),
                       advice="ask for a smaller half_size or a coarser spacing")
    r = r_c + spacing * np.arange(-n_r, n_r + 1)
    y = q[1] + spacing * np.arange(-n_y, n_y + 1)
    return r, y


def focus(echo: EchoData, est: MotionEstimate, tau_span: float | None = None, sharpen: bool = True,
          method: str = "bp", half_size=None, spacing: float | None = None, backend: str | None = None,
          progress: bool = False) -> dict:
    """The target focused at every receiver that can focus it, on the r-y plane:
    {name: Image with dims ("y", "r")}, y along-track and r the slant range from the
    transmitter, both at the reference slow time (m). Receivers in ``est.cannot_focus`` are left
    out (Table II case 7: imaged from C only).

    Parameters
    ----------
    echo : the raw EchoData ``est`` was estimated from.
    est : :class:`.motion.MotionEstimate` (:func:`clsas.estimate_motion`).
    tau_span : s of two-way delay: the image's extent in range (c tau_span / 2 m), optional.
    sharpen : remove the phase the velocity error leaves, found by image sharpness (module
        docstring; ``method="paper"``: :mod:`.sharpen` on the whole window).
    method : "bp" (default): back-projection in the target's frame, every scatterer focused
        (module docstring); "paper": the paper's chain (RCMC, RWC, azimuth compression with the
        reference point's K_a,eq and f_dc,eq and the model's higher-order terms, sections III-VI),
        whose image holds one period PRF / |K| of slow time and the range ``tau_span``.
    half_size : m, the "bp" image's half-extent around the reference point, one number or
        (range, along-track); default :data:`SIZE_FACTOR` x the target's size from the chain's
        extents plus :data:`MARGIN_M` (at least :data:`MIN_HALF_M`).
    spacing : m, the "bp" pixel spacing (default half the finest resolution cell: c / (2 B) in
        range, 0.886 |V_h| / (|K| T_a) along the track at the receivers that focus).
    backend, progress : of the back-projection.
    """
    if not isinstance(est, MotionEstimate):
        raise TypeError(f"est must be a MotionEstimate (from estimate()), got {type(est).__name__}")
    sharpen = validate.flag("focus_moving sharpen", sharpen)
    method = validate.choice("focus_moving method", method, METHODS)
    if tau_span is not None:
        tau_span = validate.positive("focus_moving tau_span", tau_span, high=10.0, unit="s")
    check_echo(echo, list(est.receivers))
    if method == "paper":
        return _focus_paper(echo, est, tau_span, sharpen)
    r, y = _axes(est, half_size, spacing, tau_span)
    grid = ry_grid(est.layout, est.position, est.velocity, r, y)
    images = {}
    for name in est.receivers:
        if name in est.cannot_focus:
            continue
        comp = compressed_receiver(echo, name)
        # the band where intra-pulse Doppler's shifted echo wraps round F_r zeroed, as the chain
        # does (:func:`.records.wrapped_band`): its ghost would focus T away in range
        _, f_dc, k = delay_terms(est.layout, name, est.position, est.velocity)
        rec = records_of(comp)
        clean = without_wrapped_band(rec, float(f_dc), float(k))
        if clean is not rec:
            comp = comp.replace(data=clean.x[None])
        provenance = {"algorithm": "clsas.estimate.moving.focus", "method": "bp", "receiver": name,
                      "velocity": est.velocity.tolist(), "position": est.position.tolist(),
                      "eta_ref": est.layout.eta_ref, "reference": "Kiang & Kiang 2022 section VI (r-y plane)",
                      "along_track_speed": along_track_speed(est.layout, name, est.position, est.velocity)}
        # the compressed peaks moved back to the delay at the pulse's centre (range-Doppler
        # coupling, :mod:`.layout`), then the residual phase phi removed (module docstring)
        shift = est.layout.range_doppler * doppler_history(est.layout, name, est.position, est.velocity, comp.eta)
        phi = np.zeros(comp.n_pulses)
        if sharpen:
            phi, p = residual_phase(comp, est.layout, name, est.position, est.velocity)
            provenance["residual_phase_cycles"] = tuple(float(c) for c in p)
        if sharpen or np.any(shift):
            x = filters.advance(comp.data[0], comp.fs, shift + phi / comp.waveform.f0, phi)
            comp = comp.replace(data=x[None])
        image = backproject(comp, grid, backend=backend, target_velocity=est.velocity, progress=progress)
        images[name] = Image(image.data, ("y", "r"), {"y": y, "r": r}, positions=grid.positions,
                             provenance={**provenance, "backprojection": image.provenance})
    return images


def _focus_paper(echo: EchoData, est: MotionEstimate, tau_span, sharpen: bool) -> dict:
    """``method="paper"``: each receiver compressed with the model's whole delay history at
    ``est``'s position and velocity (its Taylor K_a,eq and f_dc,eq at eta_ref and the terms
    beyond them), not the chain's K~ with those terms (over long apertures the SoWVD's K~ is the
    aperture's average, and the higher-order terms on top of it count the quartic twice), then
    with ``sharpen`` the phase the estimate's errors leave found by sharpness and removed
    (:mod:`.sharpen`). The image is placed by ``est``: its centre (where the centroid
    ``est.centroids[name]`` focuses with the model) at the model's y of the reference point."""
    images = {}
    for name, rx in est.receivers.items():
        if name in est.cannot_focus:
            continue
        _, f_dc, k = delay_terms(est.layout, name, est.position, est.velocity)
        model = Predicted(fm_rate=float(k), doppler_centroid=float(f_dc), tau_c=float(rx.tau_c))
        image: Image = focus_receiver(echo, name, model, tau_span=tau_span, sharpen=sharpen,
                                      higher_order=higher_order_delay(est.layout, name, est.position, est.velocity,
                                                                      echo.eta))
        # where the centre focuses (its centroid's offset from the model's, over K)
        eta_c = est.layout.eta_ref - (est.centroids[name] - model.doppler_centroid) / model.fm_rate
        ry = to_ry(image, est.layout, name, est.position, est.velocity, rx.tau_c, eta_c)
        images[name] = ry.replace(provenance={**ry.provenance, "method": "paper"})
    return images
