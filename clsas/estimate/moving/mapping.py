"""From the tau-eta plane to the r-y plane (Kiang & Kiang 2022, section VI), and the SSIM of the
result against the scan image of the mesh (section VI, Fig. 9(d); section VII-A).

The paper maps a focused image s_18(tau, eta) by

    r = c_s tau / 2,        y = (V_p - v~_y) (eta - eta_c,eq)

centred on r_0 = c_s tau_c,eq / 2. Derivation and generalisation (the printed y_0 =
-(V_p - v~_y) eta_c,eq is garbled: it is the y of eta = 0, not the centre). After range-walk
compensation with the target's f_dc,eq and azimuth compression with its K_a,eq, a scatterer
displaced by dp from the reference point has the Doppler centroid f_dc,eq + g.dp, with
g = d f_dc,eq / d p, and focuses at eta = eta_c - g.dp / K_a,eq (a residual linear phase
-2 pi (g.dp) eta shifts the compressed chirp by -(g.dp) / K). Along track (dp = dy y^):

    y - y_c = V_h (eta - eta_c),     V_h = -K_a,eq / g_y.

At transceiver A with the line of sight square to the relative velocity w = v - V_p y^,
g_y = -2 f0 w_y / (c R) and K = 2 f0 |w|^2 / (c R), so V_A = V_p - v_y: the paper's mapping. The
same formula serves B (bistatic) and the stationary sonobuoy C, for which V_C ~ -v_y: in case 7
(the target moving with the platform, V_p - v_y = 0) the paper's mapping collapses while C's
image has V_C = -3 m/s. V_h comes from the closed forms at the estimated position and velocity.

Range: a displacement dp changes the bistatic delay by (u1 + u2).dp / c, so c (tau - tau_c) / 2
is the displacement along the bistatic bisector, which for A is the slant range from A. The r
axis is anchored at the reference point's one-way range from the transmitter,
r = r_c + c (tau - tau_c) / 2 with r_c = |q - T| (section VI centres each image at r_0 =
c tau_c / 2, which for B and C is the bistatic mean range: 7.7 m and 240 m beyond A's range in
case 1); all three images then share the scan image's plane.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from ...model import Image
from ...metrics import ssim
from .closedforms import delay_terms
from .layout import Layout


def along_track_speed(layout: Layout, receiver: str, position, velocity, step: float = 1.0) -> float:
    """V_h = -K_a,eq / (d f_dc,eq / d y), m/s: how fast the image's y runs with eta at ``receiver``
    (module docstring; V_p - v_y for the paper's transceiver). 0 when K_a,eq is 0."""
    position = np.asarray(position, dtype=np.float64)
    dy = np.array([0.0, step, 0.0])
    k = delay_terms(layout, receiver, position, velocity)[2]
    g = (delay_terms(layout, receiver, position + dy, velocity)[1]
         - delay_terms(layout, receiver, position - dy, velocity)[1]) / (2 * step)
    return float(-k / g) if g != 0 else 0.0


def to_ry(image: Image, layout: Layout, receiver: str, position, velocity, tau_c: float, eta_c: float) -> Image:
    """An ("eta", "tau") image of ``receiver`` on the r-y plane: dims ("y", "r"), y increasing
    (the rows are flipped when V_h < 0: the target outruns the aperture).

    ``position`` (at slow time 0) and ``velocity`` are the target's (estimated) reference point;
    ``tau_c``, ``eta_c`` where that point focuses on the tau-eta plane. y is the along-track
    coordinate at the reference slow time ``layout.eta_ref``, r the slant range from the
    transmitter at that time.
    """
    if tuple(image.dims) != ("eta", "tau"):
        raise ValueError(f"image must have dims ('eta', 'tau') (a focus_receiver image), got {image.dims}")
    position = np.asarray(position, dtype=np.float64)
    velocity = np.asarray(velocity, dtype=np.float64)
    speed = along_track_speed(layout, receiver, position, velocity)
    if speed == 0:
        raise ValueError(f"receiver {receiver}: K_a,eq = 0 at this velocity, the image has no along-track axis")
    q = position + velocity * layout.eta_ref
    r_c = float(np.linalg.norm(q - layout.tx_position))
    r = r_c + 0.5 * layout.sound_speed * (image.axes["tau"] - tau_c)
    y = q[1] + speed * (image.axes["eta"] - eta_c)
    data = image.data
    if speed < 0:
        y, data = y[::-1], data[::-1]
    return Image(data, ("y", "r"), {"y": y, "r": r},
                 provenance={**image.provenance, "mapping": "Kiang & Kiang 2022 section VI (generalised)",
                             "along_track_speed": speed, "tau_c": float(tau_c), "eta_c": float(eta_c)})


def resample(image: Image, r, y) -> np.ndarray:
    """|image| (dims ("y", "r")) linearly interpolated onto the axes ``r`` and ``y`` (m); 0 outside."""
    ys, rs = image.axes["y"], image.axes["r"]
    mag = np.abs(image.data).astype(np.float64)
    if ys[0] > ys[-1]:
        ys, mag = ys[::-1], mag[::-1]
    interp = RegularGridInterpolator((ys, rs), mag, bounds_error=False, fill_value=0.0)
    yy, rr = np.meshgrid(np.asarray(y, dtype=np.float64), np.asarray(r, dtype=np.float64), indexing="ij")
    return interp(np.stack([yy, rr], axis=-1))


def ssim_against(image: Image, reference: Image, blur: float = 0.0) -> float:
    """SSIM (:func:`clsas.metrics.ssim`, section VII-A) of ``image`` resampled onto ``reference``'s
    r-y axes; ``blur`` (pixels) smooths both first (the scan image is a point cloud of facets)."""
    from scipy.ndimage import gaussian_filter

    a = resample(image, reference.axes["r"], reference.axes["y"])
    b = np.abs(reference.data).astype(np.float64)
    if blur > 0:
        a, b = gaussian_filter(a, blur), gaussian_filter(b, blur)
    return ssim(a, b)
