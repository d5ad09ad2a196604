"""Point-response helpers the reproductions share: a patch of an image around a point,
back-projection on the same pixels, and the quality figures (azimuth PSLR, IRW, 1-D and 2-D
ISLR) the papers' tables print."""

from __future__ import annotations

import numpy as np

PATCH = 0.6  # m either side of a point: the pixels back-projected and measured


def patch(image, point, half=PATCH):
    """The part of ``image`` (dims ("y", "x")) within +-``half`` m of ``point`` (x, y, z): one
    number for both dims, or a pair (half_y, half_x)."""
    from clsas.model import Image

    half_y, half_x = (half, half) if np.ndim(half) == 0 else half
    y, x = image.axes["y"], image.axes["x"]
    rows = np.flatnonzero(np.abs(y - point[1]) <= half_y)
    cols = np.flatnonzero(np.abs(x - point[0]) <= half_x)
    sub = np.ix_(rows, cols)
    return Image(data=image.data[sub], dims=("y", "x"), axes={"y": y[rows], "x": x[cols]},
                 positions=image.positions[sub])


def backprojected(echo, pixels, aperture, backend="opencl"):
    """Back-projection of ``echo`` on the pixels of the Image ``pixels`` (sinc8)."""
    import clsas
    from clsas.model import Grid, Image

    bp = clsas.backproject(echo, Grid.points(pixels.positions, dims=("y", "x")), backend=backend, interp="sinc8",
                           aperture=aperture, progress=False)
    return Image(data=bp.data, dims=("y", "x"), axes=pixels.axes, positions=pixels.positions)


def upsample_cuts(data: np.ndarray, factor: int) -> np.ndarray:
    """:func:`clsas.metrics.upsample_cut` of every row of ``data`` (n_rows, n) at once (the same
    trigonometric interpolation, each row's band placed where its smoothed power spectrum is
    weakest): complex128 (n_rows, n * factor)."""
    x = np.asarray(data, dtype=np.complex128)
    n = x.shape[1]
    spec = np.fft.fft(x, axis=1)
    width = max(1, n // 16)
    power = np.abs(spec) ** 2
    # upsample_cut's circular moving average: smooth[m] = mean of power[m + (width - 1) // 2 - j], j < width
    smooth = sum(np.roll(power, j - (width - 1) // 2, axis=1) for j in range(width)) / width
    shift = np.argmin(smooth, axis=1) - n // 2  # each row's gap moved to the Nyquist position
    rolled = np.take_along_axis(spec, (np.arange(n)[None, :] + shift[:, None]) % n, axis=1)
    if factor == 1:
        padded = rolled
    else:
        padded = np.zeros((x.shape[0], n * factor), np.complex128)
        pos = (n + 1) // 2
        padded[:, :pos] = rolled[:, :pos]
        padded[:, n * factor - (n - pos):] = rolled[:, pos:]
        if n % 2 == 0:
            padded[:, n // 2] = 0.5 * rolled[:, n // 2]
            padded[:, n * factor - n // 2] = 0.5 * rolled[:, n // 2]
    y = np.fft.ifft(padded, axis=1) * factor
    return y * np.exp(2j * np.pi * shift[:, None] * (np.arange(n * factor)[None, :] / factor) / n)


def _upsample_2d(data: np.ndarray, factor: int) -> np.ndarray:
    """Every column, then every row of ``data`` upsampled ``factor`` times (:func:`upsample_cuts`)."""
    return upsample_cuts(upsample_cuts(np.asarray(data).T, factor).T, factor)


def _null(mag: np.ndarray, start: int, step: int) -> int:
    j = start
    while 0 <= j + step < mag.size and mag[j + step] < mag[j]:
        j += step
    return j


def islr_2d(image, near, radius: float, extent: float = 10.0, upsample: int = 8) -> float:
    """The 2-D integrated side-lobe ratio of the point near ``near`` = (y, x) (m) in ``image``
    (dims ("y", "x"), uniform axes), dB: 10 log10 of the energy within ``extent`` IRWs of the peak
    in both dims outside the main lobe, over the main lobe's, the main lobe being the rectangle
    between the first minima of the two cuts through the peak (after ``upsample`` x FFT
    interpolation in each dim)."""
    from clsas import metrics, validate

    extent = validate.scalar("islr_2d extent", extent, low=1.0, low_open=True, high=1e3, unit="IRWs")
    upsample = validate.integer("islr_2d upsample", upsample, low=1, high=64)
    q = metrics.analyse_point(image, near=near, radius=radius)
    mag = np.abs(_upsample_2d(np.asarray(image.data), upsample)) ** 2
    ys, xs = image.axes["y"], image.axes["x"]
    iy = int(round((q["y"].location - ys[0]) / (ys[1] - ys[0]) * upsample))
    ix = int(round((q["x"].location - xs[0]) / (xs[1] - xs[0]) * upsample))
    span_y = extent * q["y"].irw / (ys[1] - ys[0]) * upsample
    span_x = extent * q["x"].irw / (xs[1] - xs[0]) * upsample
    if not (span_y <= iy < mag.shape[0] - span_y and span_x <= ix < mag.shape[1] - span_x):
        raise ValueError(f"islr_2d: the patch is smaller than +-{extent} IRWs around the point at {near}")
    row, col = mag[iy], mag[:, ix]
    main = np.zeros(mag.shape, bool)
    main[_null(col, iy, -1):_null(col, iy, 1) + 1, _null(row, ix, -1):_null(row, ix, 1) + 1] = True
    k_y, k_x = np.arange(mag.shape[0])[:, None] - iy, np.arange(mag.shape[1])[None, :] - ix
    region = (np.abs(k_y) <= span_y) & (np.abs(k_x) <= span_x)
    return float(10 * np.log10(mag[region & ~main].sum() / mag[main].sum()))


def quality(image, point) -> dict:
    """Azimuth PSLR and IRW (AR), 1-D azimuth ISLR and the 2-D ISLR of the point (x, y, z) in
    the patch ``image``, and its location error (m)."""
    from clsas import metrics

    near, radius = (point[1], point[0]), 0.02
    q = metrics.analyse_point(image, near=near, radius=radius)
    return {"PSLR": q["y"].pslr_db, "ISLR": islr_2d(image, near, radius), "ISLR 1-D": q["y"].islr_db,
            "AR": q["y"].irw, "dy": q["location"][0] - point[1], "dx": q["location"][1] - point[0]}
