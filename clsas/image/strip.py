"""The strip-map imager template: one signature, one set of checks and one path for the
frequency-domain imagers (omega-k, range-Doppler, chirp scaling, nonlinear chirp scaling).

Every imager is ``imager(data, **options)`` with the keyword-only options of :func:`strip_job`
(the same names and defaults for all of them) and runs the same three steps::

    job = strip_job("range_doppler", data, **options)   # checks, the record, its Doppler rows
    focused, r = ...                                     # the algorithm: (len(job.rows), len(r))
    return strip_image(job, focused, r)                  # band weights, along-track shift, Image

``focused`` is the algorithm's result in the range-Doppler domain: one row per Doppler row the
processed band keeps (``job.rows`` of the along-track FFT, wavenumbers ``job.ku``), one column
per slant range ``r``, range-compressed, migration-corrected and azimuth-compressed but not yet
weighted. Rows outside the band (|k_u| > 2 pi / D with ``elements``) are never computed: their
weight is zero.

Defaults, one rule: nothing is weighted unless asked. ``window="none"`` as in
:func:`clsas.range_compress`, :func:`clsas.backproject` and :func:`clsas.ptrs_image`: a point's
response is then the unweighted one theory gives (PSLR -13.3 dB, IRW 0.886 of a cell) whichever
imager made it, so images of different imagers compare like for like, and a window is a choice
the user names. (omega-k used to default to "hamming", range-Doppler and chirp scaling to "none".)
"""

from __future__ import annotations

import inspect
import itertools
from dataclasses import dataclass

import numpy as np
import scipy.fft

from .. import backend as _backend
from .. import budget
from .. import validate as v
from ..interp import INTERPOLATORS, TAP_WINDOWS
from ..model import EchoData, Image
from ..pulse import check_window
from .rangecomp import check_workers
from ..kernelmath import unit_phasor
from .record import LineRecord, as_record, azimuth_weights, check_elements, element_lengths, image_of, oversampling

MIN_SAMPLES = 16  # samples a record: the longest interpolator (sinc16) reads 16
MIN_ROWS = 2  # along-track samples
BYTES_PER_SAMPLE = 128  # an imager's 2-D spectra, phase screens and interpolation temporaries, per record sample
GAIN_MARGIN = 16.0  # beyond the transforms' gain (rows x samples): deconvolution, band weights, filter gains


@dataclass(frozen=True)
class StripJob:
    """One strip-map imaging job, checked: the record, the Doppler rows to compute and the options.

    algorithm : the imager's name (messages and provenance).
    record : the LineRecord imaged.
    n_ku : length of the along-track FFT.
    rows : int (n_rows,), the rows of that FFT the processed band keeps.
    ku : float (n_rows,), their along-track wavenumbers, rad/m.
    weights : float32 (n_rows,), the band's weighting and element-pattern deconvolution.
    elements, deconvolve, window, window_options, interp, tap_window, depth, workers, backend :
        the options of :func:`strip_job`, checked (``backend`` resolved to "numpy" or "opencl").
    """

    algorithm: str
    record: LineRecord
    n_ku: int
    rows: np.ndarray
    ku: np.ndarray
    weights: np.ndarray
    elements: tuple | None
    deconvolve: bool
    window: str
    window_options: dict
    interp: str
    tap_window: str
    depth: float | None
    workers: int
    backend: str

    @property
    def oversampling(self) -> float:
        """The record's sampling rate over its band (the Knab window's parameter)."""
        return oversampling(self.record.fs, self.record.waveform)

    @property
    def ku_nyquist(self) -> float:
        """The largest |k_u| the along-track sampling holds (rad/m): the edge of the sampled band."""
        return float(np.abs(along_track_wavenumbers(self.record, self.n_ku)).max())

    def check_budget(self, columns: int, bytes_per_sample: float) -> None:
        """The memory budget for an algorithm's arrays of the kept rows by ``columns`` range
        samples (a padded range axis), ``bytes_per_sample`` bytes a sample in all."""
        budget.check_bytes(f"{self.algorithm} of {self.rows.size} Doppler rows x {columns} range samples",
                           bytes_per_sample * float(self.rows.size) * columns,
                           "image a shorter stretch of the track or of the swath at a time")

    def doppler(self, data: np.ndarray) -> np.ndarray:
        """The kept rows of the along-track FFT of ``data`` (n_u, n): complex (n_rows, n)."""
        return scipy.fft.fft(data, n=self.n_ku, axis=0, workers=self.workers)[self.rows]


def strip_job(algorithm: str, data, *, receiver=0, elements=None, deconvolve: bool = True, window: str = "none",
              interp: str = "sinc8", tap_window: str = "kaiser", depth: float | None = None,
              workers: int | None = None, backend: str | None = None, **window_options) -> StripJob:
    """Check a strip-map imager's arguments (before anything large is allocated) and make its record.

    Parameters (the template's, the same for every strip-map imager)
    ----------
    data : LineRecord, or a range-compressed monostatic EchoData (then ``receiver`` picks the
        receiver that sits with the transmitter; :func:`clsas.image.record.line_record`).
    receiver : index or name of that receiver (EchoData only).
    elements : (L_tx, L_rx) along-track element lengths, m (one number: both): the processed
        Doppler band |k_u| <= 2 pi / max(L) and the element-pattern deconvolution (Heremans 2009
        eqs. 44-45). None keeps the whole sampled band.
    deconvolve : divide by the element pattern A(k_u); False keeps its taper, as back-projection
        does (for like-for-like comparisons).
    window : weighting of the processed band ("none", "hamming", "taylor", "kaiser"; their
        options ``taylor_nbar``, ``taylor_sll_db``, ``kaiser_beta`` as keywords); the range
        weighting is the range compression's. Default "none" (module docstring).
    interp, tap_window : every interpolation the imager runs (an EchoData's path-excess
        compensation, range-Doppler's migration correction, omega-k's Stolt map):
        "linear", "sinc8", "sinc16"; "kaiser" or "knab" (:mod:`clsas.interp`).
    depth : m, the horizontal plane the image's pixels are placed on (default: the track's).
    workers : scipy.fft threads (default: all cores).
    backend : where the interpolations run ("numpy", "opencl", "auto", None: the default); the
        FFTs and phase screens run on the host.

    Returns
    -------
    StripJob
    """
    name = f"{algorithm} data"
    v.instance(name, data, (LineRecord, EchoData), "a LineRecord or a range-compressed monostatic EchoData")
    rows, samples = (data.n_pulses, data.n_samples) if isinstance(data, EchoData) else (data.n_u, data.n_samples)
    v.integer(f"{name}: samples a record", samples, low=MIN_SAMPLES, why="the interpolators read up to 16")
    v.integer(f"{name}: along-track samples (pulses)", rows, low=MIN_ROWS, why="a strip-map image needs 2")
    deconvolve = v.flag(f"{algorithm} deconvolve", deconvolve)
    window_options = check_window(window, window_options, algorithm)
    v.choice(f"{algorithm} interp", interp, INTERPOLATORS)
    v.choice(f"{algorithm} tap_window", tap_window, TAP_WINDOWS)
    if depth is not None:
        depth = v.scalar(f"{algorithm} depth", depth, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE, unit="m")
    workers = check_workers(workers, f"{algorithm} workers")
    element_lengths(f"{algorithm} elements", elements)
    backend = _backend.resolve(backend)
    if isinstance(data, EchoData):
        v.compression(name, data)
    elif not (v.is_number(receiver, "iu") and receiver == 0):
        raise ValueError(f"{algorithm} receiver: a LineRecord holds one record; receiver picks one of an EchoData's, "
                         f"got {receiver!r}")
    elif not v.all_finite(data.data):
        raise ValueError(f"{name}: the LineRecord's samples must be finite; it has NaN or inf")
    budget.check_bytes(f"{algorithm} of {rows} pulses x {samples} samples", BYTES_PER_SAMPLE * float(rows) * samples,
                       "image a shorter stretch of the track or of the swath at a time")
    peak = float(np.abs(data.data).max())
    if peak * GAIN_MARGIN * rows * samples > float(np.finfo(np.float32).max):
        raise ValueError(f"{name}: samples up to {peak:.3g} could overflow complex64 in the imager's transforms (a gain "
                         f"up to {rows} x {samples}); scale the record down")

    record = as_record(data, receiver, backend, interp, tap_window)
    elements = check_elements(elements, record)
    n_ku = scipy.fft.next_fast_len(record.n_u)
    ku = along_track_wavenumbers(record, n_ku)
    weights = azimuth_weights(ku, elements, window, deconvolve, **window_options)
    kept = np.flatnonzero(weights != 0)
    return StripJob(algorithm=algorithm, record=record, n_ku=n_ku, rows=kept, ku=ku[kept],
                    weights=weights[kept].astype(np.float32), elements=elements, deconvolve=deconvolve, window=window,
                    window_options=window_options, interp=interp, tap_window=tap_window, depth=depth, workers=workers,
                    backend=backend)


def along_track_wavenumbers(rec: LineRecord, n_ku: int) -> np.ndarray:
    """k_u (rad/m) of the rows of an along-track FFT of length n_ku (FFT order)."""
    return 2 * np.pi * np.fft.fftfreq(n_ku, rec.du)


def nonstop_shift(rec: LineRecord, ku: np.ndarray, r: np.ndarray) -> np.ndarray | float:
    """exp(-j k_u v r / c) for rows ku and ranges r (Huang & Yang 2022 eq. 25 with
    f_t = v k_u / (2 pi)): moves the echo of a target at range r from u = y - v r / c (the
    non-stop-and-go phase centre) back to its true along-track position y; 1 for stop-and-go.
    complex64 (len(ku), len(r))."""
    if not rec.nonstop:
        return 1.0
    return unit_phasor(np.outer(ku, -rec.speed / rec.medium.sound_speed * np.asarray(r)))


def strip_image(job: StripJob, focused: np.ndarray, r: np.ndarray, **provenance) -> Image:
    """The Image of a strip-map imager's result: the band's weights, the non-stop-and-go
    along-track shift (Huang & Yang 2022 eq. 25), the inverse along-track FFT, the recorded
    ranges on the plane z = ``job.depth`` (:func:`clsas.image.record.image_of`).

    focused : complex (len(job.rows), len(r)), the range-Doppler rows ``job.rows`` (changed in place).
    r : float (n,), slant range of each column, m, increasing.
    provenance : what the algorithm adds to the image's provenance.
    """
    rec = job.record
    focused *= nonstop_shift(rec, job.ku, r)
    focused *= job.weights[:, None]
    full = np.zeros((job.n_ku, focused.shape[1]), np.complex64)
    full[job.rows] = focused
    params = {"elements": job.elements, "deconvolve": job.deconvolve, "window": job.window, "interp": job.interp,
              "tap_window": job.tap_window, "backend": job.backend, **provenance}
    image = image_of(rec, full, r, job.algorithm, params, job.depth, job.workers)
    v.finite_result(f"{job.algorithm}: the image", image.data, "scale the record down")
    return image


def range_blocks(r: np.ndarray, width: float) -> list[tuple[int, int, float]]:
    """Equal range sub-blocks at most ``width`` m wide over the columns of ranges ``r`` (m,
    increasing): (first column, stop column, centre range, m) each."""
    n_blocks = max(1, min(r.size, int(np.ceil((r[-1] - r[0]) / width))))
    edges = np.linspace(0, r.size, n_blocks + 1).astype(int)
    return [(int(lo), int(hi), float(r[(lo + hi - 1) // 2])) for lo, hi in itertools.pairwise(edges)]


def block_segment(lo: int, hi: int, margin: int, n: int) -> tuple[np.ndarray, int]:
    """The overlap-save segment of the columns [lo, hi) of a circular range axis of n columns,
    with ``margin`` columns on each side: (its column indices, mod n; the position of column lo
    in it). The whole axis, from lo on, when the segment would be as long."""
    pad, length = margin, scipy.fft.next_fast_len(hi - lo + 2 * margin)
    if length >= n:
        pad, length = 0, n
    return np.arange(lo - pad, lo - pad + length) % n, pad


def follows_template(imager):
    """Give a strip-map imager ``imager(data, **options)`` the template's signature (for help()
    and inspect): ``data`` and the keyword-only options of :func:`strip_job`."""
    params = list(inspect.signature(strip_job).parameters.values())[1:]
    imager.__signature__ = inspect.Signature(params, return_annotation=Image)
    return imager
