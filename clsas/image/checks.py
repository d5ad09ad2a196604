"""Argument checks shared by the frequency-domain imagers (omega_k, range_doppler, chirp_scaling),
made before any record is built: the window and its options, the FFT threads, the image plane's
depth, and records long enough for the interpolators."""

from __future__ import annotations

from .. import budget
from .. import validate as v
from ..model import EchoData
from .rangecomp import check_window, check_workers
from .record import LineRecord

MIN_SAMPLES = 16  # samples a record: the longest interpolator (sinc16) reads 16
MIN_ROWS = 2  # along-track samples
BYTES_PER_SAMPLE = 128  # an imager's 2-D spectra, phase screens and interpolation temporaries, per record sample


def check_imager(caller: str, data, window, window_options: dict, workers, depth) -> tuple[dict, int]:
    """Validate an imager's common arguments; returns (window options with their defaults, workers)."""
    if isinstance(data, EchoData):
        rows, samples = data.n_pulses, data.n_samples
    elif isinstance(data, LineRecord):
        rows, samples = data.n_u, data.n_samples
    else:
        raise TypeError(f"{caller} data: must be a LineRecord or a range-compressed monostatic EchoData, got "
                        f"{type(data).__name__}")
    if samples < MIN_SAMPLES:
        raise ValueError(f"{caller} data: records of {samples} samples are too short; the interpolators need at least "
                         f"{MIN_SAMPLES} a record")
    if rows < MIN_ROWS:
        raise ValueError(f"{caller} data: {rows} along-track sample(s) (pulses); a strip-map image needs at least "
                         f"{MIN_ROWS}")
    budget.check_bytes(f"{caller} of {rows} pulses x {samples} samples", BYTES_PER_SAMPLE * float(rows) * samples,
                       "image a shorter stretch of the track or of the swath at a time")
    options = check_window(window, window_options, caller)
    if depth is not None:
        v.scalar(f"{caller} depth", depth, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE, unit="m")
    return options, check_workers(workers, f"{caller} workers")
