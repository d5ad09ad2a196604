"""Echo synthesis: ``simulate(scenario) -> EchoData`` and ``delays(scenario)``.

Pass A computes every path's delay (the recording window follows from them), pass B the
records, a block of pulses at a time so that memory stays bounded; the backends are in
:mod:`.reference` and :mod:`.launch`. The OpenCL grid route (large scenes) runs in one pass: the
records over a window that bounds every delay, the extents from the same paths, then the
recording window cut from it (:func:`_one_pass_window`).

Noise (``snr_db``, ``snr_reference``): :mod:`.noise`.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from ...progress import Progress, stage
from ...model import EchoData
from ...scene.scenario import Scenario
from ..occlusion import DEFAULT_REUSE_TOLERANCE, PathWeights, has_meshes, needs_path_weights, scene_scatterers
from ...validate import choice
from ..checks import check_arguments, warn_pulse_overlap
from ..window import check_cube_size, node_span, receiver_nodes
from .options import AUTO, DEFAULT_CHUNK_BYTES, SynthesisOptions, auto_flag
from ..propagation import boundaries, path_kinds
from .compressed import DEFAULT_LEVEL_DB
from .grid import RATE
from .launch import OpenCLSynth
from .noise import SNR_REFERENCES, add_noise
from .physics import Physics
from .records import path_record
from .reference import NumpySynth
from .resolve import delay_bound, grid_plan, resolve_physics


def _pulse_blocks(n_pulses: int, per_pulse_bytes: int, chunk_bytes: int) -> list[slice]:
    size = int(max(1, min(n_pulses, chunk_bytes // max(1, per_pulse_bytes))))
    return [slice(s, min(s + size, n_pulses)) for s in range(0, n_pulses, size)]


def _window(scenario: Scenario, lo: np.ndarray, hi: np.ndarray):
    """(t0 per receiver, valid samples per receiver, origin text) from the delay extents lo/hi (H, N)."""
    wf = scenario.waveform
    if scenario.recording is not None:
        t0, n_valid = scenario.recording.for_receivers(scenario.n_receivers)
        return np.asarray(t0, float), np.asarray(n_valid, np.int64), "given by Scenario.recording"
    first = np.floor((lo.min(axis=1) - 0.5 * wf.duration) * wf.fs)
    last = np.ceil((hi.max(axis=1) + 0.5 * wf.duration) * wf.fs)
    return first / wf.fs, (last - first + 1).astype(np.int64), "derived from the geometry"


def _check_targets_in_windows(scenario: Scenario, lo, hi, t0, n_valid) -> None:
    wf = scenario.waveform
    end = t0 + (n_valid - 1) / wf.fs
    heard = ((hi + 0.5 * wf.duration) >= t0[:, None]) & ((lo - 0.5 * wf.duration) <= end[:, None])
    # a facet no pulse's beam reaches carries no echo (lo = inf): not an error
    deaf = np.flatnonzero(~heard.any(axis=0) & np.isfinite(lo).any(axis=0))
    if deaf.size:
        raise ValueError(
            f"{deaf.size} scatterer(s) (indices {deaf[:5].tolist()}{'...' if deaf.size > 5 else ''}) echo "
            f"between {lo[:, deaf[0]].min():.6g} and {hi[:, deaf[0]].max():.6g} s, outside every recording "
            f"window (Scenario.recording: starts {np.round(t0, 6).tolist()} s, {n_valid.tolist()} samples); "
            "move the targets or widen the window"
        )


def _with_mesh_weights(scenario: Scenario, occlusion, stop_and_go: bool, hull_occlusion: bool,
                       reuse_tolerance: float):
    """The user's occlusion factor times the path weights of mesh targets (hull visibility and
    angular law) and of the seafloor's facets (:class:`clsas.synthesis.occlusion.PathWeights`)."""
    if not needs_path_weights(scenario):
        return occlusion
    mesh = PathWeights(scenario, stop_and_go=stop_and_go, hull_occlusion=hull_occlusion,
                       reuse_tolerance=reuse_tolerance)
    if occlusion is None:
        return mesh
    if callable(occlusion):
        return lambda pulses: mesh(pulses) * np.asarray(occlusion(pulses), dtype=np.float64)
    return lambda pulses: mesh(pulses) * occlusion[:, pulses]


def nothing_heard(scenario: Scenario) -> ValueError:
    """The error for a scenario none of whose pulses hears a scatterer (no target, and no seafloor
    or one outside the transmitter's beam at every pulse)."""
    if scenario.seafloor is not None:
        return ValueError(f"Scenario.seafloor (extent {list(scenario.seafloor.extent)} m) lies outside the "
                          f"transmitter's beam at every pulse (eta {scenario.eta[0]:.6g} .. {scenario.eta[-1]:.6g} s) "
                          f"and Scenario.targets is empty: nothing to simulate; move the seafloor or the track")
    return ValueError("Scenario.targets is empty and there is no seafloor: add PointTargets, a mesh target or a "
                      "Seafloor to simulate echoes")


def _make_synth(scenario: Scenario, opts: SynthesisOptions, occlusion, prune: bool = True):
    """The backend's synthesizer and the pulse blocks that keep its working memory under ``opts.chunk_bytes``."""
    scat = scene_scatterers(scenario)
    if scat.count == 0:
        raise nothing_heard(scenario)
    n_rx, n_pulses = scenario.n_receivers, scenario.eta.size
    if occlusion is not None and not callable(occlusion):
        occlusion = np.asarray(occlusion, dtype=np.float64)
        if occlusion.shape not in ((n_rx, n_pulses, scat.count), (1, n_pulses, scat.count)):
            raise ValueError(f"occlusion must have shape (n_rx, n_pulses, n_scatterers) = "
                             f"{(n_rx, n_pulses, scat.count)} (or (1, n_pulses, n_scatterers): shared by the "
                             f"receivers), got {occlusion.shape}")
    occlusion = _with_mesh_weights(scenario, occlusion, opts.stop_and_go, opts.hull_occlusion, opts.reuse_tolerance)
    physics = resolve_physics(scenario, opts, scat, prune)
    physics = dataclasses.replace(physics, grid=grid_plan(scenario, opts, scat, physics))
    args = (scenario, scat, occlusion, physics)
    kinds = len(physics.kinds)
    if opts.backend == "numpy":
        span = int(0.5 * scenario.waveform.duration * scenario.waveform.fs) + 2
        synth = NumpySynth(*args)
        per_pulse = n_rx * scat.count * kinds * (16 * 8 + 48 * span)
    else:
        tau_hi = node_span(scenario, scenario.eta, delay_bound(scenario, scat, physics))
        synth = OpenCLSynth(*args, double=opts.double,
                             nodes=receiver_nodes(scenario, scenario.eta, tau_hi, strict=not opts.stop_and_go))
        per_pulse = n_rx * scat.count * kinds * path_record(synth.real, physics.extended).itemsize
    return synth, _pulse_blocks(n_pulses, per_pulse, opts.chunk_bytes)


def delays(scenario: Scenario, backend: str | None = None, stop_and_go: bool = False, path: str = "D-D") -> np.ndarray:
    """Exact two-way delays of every (receiver, pulse, scatterer) path, s, shape (H, P, N).

    ``path`` names the path kind: "D-D" the direct path, else the outgoing and the return leg's
    bounces off the sea surface (S) and the seabed (B) in the order the wave meets them from
    the transmitter / the receiver, e.g. "S-D", "D-B", "SB-D", "S-S" (the scenario's
    ``surface`` and ``seafloor``; :mod:`clsas.synthesis.propagation`).
    The NumPy backend iterates the fixed point of :mod:`clsas.geometry`; the OpenCL
    kernel solves each leg in closed form (kernels/geometry.h, ``meet_time8``) and returns the
    delay as the sample index it hands to the accumulation (float32 fraction: ~3e-12 s at 20 kHz).
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    names = [kind.name for kind in path_kinds(boundaries(scenario), 2)]
    if path not in names:
        raise ValueError(f"delays path: must be one of this scenario's path kinds {names}, got {path!r}")
    order = sum(ch in "SB" for ch in path)
    synth, blocks = _make_synth(scenario, SynthesisOptions(backend=backend, stop_and_go=stop_and_go, multipath=order,
                                                           spreading=False, absorption=False), None, prune=False)
    kind = [k.name for k in synth.physics.kinds].index(path)
    return np.concatenate([synth.delays(sl, kind) for sl in blocks], axis=1)


def window_extents(scenario: Scenario, options: SynthesisOptions | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per receiver (H,), the echo-centre extents in whole samples from t = 0 (floor of the
    earliest, floor of the latest + 1) over the scenario's pulses, the path kinds ``options``
    resolve to, and the scatterers each pulse hears (the seafloor's facets in its beam's reach):
    the extents :func:`simulate` derives its recording window from (pass A). inf, -inf for a
    receiver that hears nothing. For splitting a run into pulse blocks (:mod:`clsas.distributed`)."""
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    opts = SynthesisOptions() if options is None else options
    if not isinstance(opts, SynthesisOptions):
        raise TypeError(f"options must be a SynthesisOptions, got {type(opts).__name__}")
    if scenario.seafloor is not None and scene_scatterers(scenario).count == 0:  # the beam reaches no facet
        return np.full(scenario.n_receivers, np.inf), np.full(scenario.n_receivers, -np.inf)
    synth, blocks = _make_synth(scenario, opts, None)
    lo = np.full((scenario.n_receivers, synth.scat.count), np.inf)
    hi = np.full((scenario.n_receivers, synth.scat.count), -np.inf)
    for sl in blocks:
        synth.extents(sl, lo, hi)
    return lo.min(axis=1), hi.max(axis=1)


class Synthesis(NamedTuple):
    """What :func:`synthesize` returns.

    data : (n_rx, n_pulses, n_samples) in the options' dtype; t0 : (n_rx,) s, the windows' starts;
    n_valid : (n_rx,) samples each window holds; origin : where the window came from (text);
    nodes : (rx_tau (n_nodes,) s, rx_pos (n_rx, n_pulses, n_nodes, 3) m), the receivers'
    positions over each pulse; node_error_m : their largest departure from the exact track;
    n_scatterers : point scatterers synthesized (mesh facets included);
    physics : what the paths carried (:class:`clsas.synthesis.echo.physics.Physics`).
    """

    data: np.ndarray
    t0: np.ndarray
    n_valid: np.ndarray
    origin: str
    nodes: tuple
    node_error_m: float
    n_scatterers: int
    physics: Physics


def synthesize(scenario: Scenario, options: SynthesisOptions | None = None, occlusion=None) -> Synthesis:
    """The echo cube of ``scenario`` and its recording windows, without noise: both passes of
    :func:`simulate` (see there for ``occlusion`` and for what ``options`` mean), with the
    samples returned in ``options.dtype``. With ``SynthesisOptions(backend="numpy",
    dtype=numpy.complex128)`` this is the float64 NumPy reference the OpenCL kernels are held to
    (and ``backend="opencl", precision="double", dtype=numpy.complex128`` the double kernels'
    own samples); :func:`simulate` wraps its complex64 result into an EchoData.
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    opts = SynthesisOptions() if options is None else options
    if not isinstance(opts, SynthesisOptions):
        raise TypeError(f"options must be a SynthesisOptions, got {type(opts).__name__}")
    if scenario.recording is not None:
        _, n_valid = scenario.recording.for_receivers(scenario.n_receivers)
        check_cube_size(scenario.n_receivers, scenario.eta.size, int(np.max(n_valid)), opts.max_bytes,
                        "given by Scenario.recording")
    synth, blocks = _make_synth(scenario, opts, occlusion)
    wf = scenario.waveform
    n_rx, n_pulses, n_scat = scenario.n_receivers, scenario.eta.size, synth.scat.count
    lo = np.full((n_rx, n_scat), np.inf)
    hi = np.full((n_rx, n_scat), -np.inf)
    bound = _one_pass_window(scenario, opts, synth)
    if bound is None:  # pass A: the delays, for the recording window
        with stage(f"echo delays ({opts.backend})", f"{n_rx} receivers x {n_pulses} pulses x {n_scat} scatterers"), \
                Progress(n_pulses, "pulses", "echo delays", opts.progress, leave=False) as bar:
            for sl in blocks:
                synth.extents(sl, lo, hi)
                bar.done(sl.stop - sl.start)
    else:  # one pass over a window that holds the recording window: pass B widens the extents
        t0_b, n_b = bound
        data_b = _records(scenario, opts, synth, t0_b, n_b, (lo, hi))
    warn_pulse_overlap(scenario, synth)
    lo, hi = lo / wf.fs, hi / wf.fs  # s, whole samples
    # the nodes span the recording window (and not beyond sampled motion errors)
    tau_span = node_span(scenario, scenario.eta, hi.max() + 0.5 * wf.duration + 2 / wf.fs)
    if opts.backend == "opencl" and bound is None and hi.max() > synth.rx_tau[-1]:
        synth = OpenCLSynth(*synth.args, double=opts.double,
                             nodes=receiver_nodes(scenario, scenario.eta, tau_span, strict=not opts.stop_and_go))
    t0, n_valid, origin = _window(scenario, lo, hi)
    _check_targets_in_windows(scenario, lo, hi, t0, n_valid)
    n_samples = int(n_valid.max())
    nodes = (synth.rx_tau, synth.rx_pos, synth.rx_node_error) if opts.backend == "opencl" else \
        (lambda n: (n[0], n[1], n[3]))(receiver_nodes(scenario, scenario.eta, tau_span, strict=False))
    check_cube_size(n_rx, n_pulses, n_samples, opts.max_bytes, origin, n_nodes=nodes[0].size)
    if bound is None:
        data = _records(scenario, opts, synth, t0, n_valid)
    else:
        data = np.zeros((n_rx, n_pulses, n_samples), dtype=opts.dtype)
        shift = np.round((t0 - t0_b) * wf.fs).astype(np.int64)
        if np.any(shift < 0) or np.any(shift + n_valid > n_b):
            raise RuntimeError(f"echo synthesis: the recording window (starts {t0.tolist()} s, {n_valid.tolist()} "
                               f"samples) is not inside its bound (starts {t0_b.tolist()} s, {n_b.tolist()}): a bug")
        for h in range(n_rx):
            data[h, :, :n_valid[h]] = data_b[h, :, shift[h]:shift[h] + n_valid[h]]
        del data_b
    return Synthesis(data, t0, n_valid, origin, nodes[:2], float(nodes[2]), n_scat, synth.physics)


def _one_pass_window(scenario: Scenario, opts: SynthesisOptions, synth):
    """(t0 (H,) s, samples (H,)) of a window that holds every echo, from the delays' bounds
    (:meth:`.launch.OpenCLSynth.delay_bounds`), for a synthesis in one pass (records and extents
    from the same paths, then cut to the recording window): the OpenCL grid route of a scene
    whose window is derived from the geometry, when the bound's cube fits the memory budget.
    None: two passes (the delays first)."""
    if opts.backend != "opencl" or synth.physics.grid is None or scenario.recording is not None:
        return None
    wf = scenario.waveform
    lo, hi = synth.delay_bounds()
    if not np.all(np.isfinite(lo)):
        return None
    lo_s, hi_s = np.floor(lo * wf.fs) / wf.fs, (np.floor(hi * wf.fs) + 1) / wf.fs  # whole samples, as the extents
    first = np.floor((lo_s - 0.5 * wf.duration) * wf.fs) - 1  # _window's arithmetic, and a sample to spare
    last = np.ceil((hi_s + 0.5 * wf.duration) * wf.fs) + 1
    n_b = (last - first + 1).astype(np.int64)
    if 2 * scenario.n_receivers * scenario.eta.size * int(n_b.max()) * np.dtype(opts.dtype).itemsize > opts.max_bytes:
        return None
    if hi.max() + 0.5 * wf.duration > synth.rx_tau[-1]:  # the nodes must span the bound's window
        return None
    return first / wf.fs, n_b


def _records(scenario: Scenario, opts: SynthesisOptions, synth, t0: np.ndarray, n_valid: np.ndarray, extents=None):
    """Pass B: the records (H, P, max n_valid) in ``opts.dtype``, receiver h's window starting at
    t0[h] with n_valid[h] samples (zeros beyond), in pulse blocks that also bound the records'
    memory (complex128 on the host, the kernel's output buffer and its copy; the raw route's FFTs
    of about twice the samples; the grid route's grids); ``extents`` (lo, hi) widened on the way
    (:meth:`.launch.OpenCLSynth.records`)."""
    wf, name = scenario.waveform, opts.backend
    n_rx, n_pulses, n_scat = scenario.n_receivers, scenario.eta.size, synth.scat.count
    n_samples = int(np.max(n_valid))
    data = np.zeros((n_rx, n_pulses, n_samples), dtype=opts.dtype)
    per_pulse = n_rx * (n_scat * 32 + (7 if synth.physics.compress_raw else 3) * 16 * n_samples)
    if synth.physics.grid is not None:  # the grids, their spectra and the tails
        per_pulse += n_rx * 3 * 16 * (synth.physics.grid.terms * RATE + 1) * synth.physics.grid.grid_samples(n_samples)
    with stage(f"echo synthesis ({name})", f"{n_rx} receivers x {n_pulses} pulses x {n_samples} samples "
               f"({data.nbytes / 2**20:.1f} MiB) x {n_scat} scatterers"), \
            Progress(n_pulses, "pulses", f"echo synthesis ({name})", opts.progress) as bar:
        for sl in _pulse_blocks(n_pulses, per_pulse, opts.chunk_bytes):
            block = synth.records(sl, t0, n_samples) if extents is None else synth.records(sl, t0, n_samples, extents)
            if synth.physics.compress_raw:  # the raw route into the compressed domain (.compressed)
                for h in range(n_rx):
                    block[h, :, n_valid[h]:] = 0
                block = synth.physics.response.compress(block, wf)
            if not np.all(np.isfinite(block)):
                raise ValueError("the echo has non-finite samples: a scatterer coincides with the transmitter or a "
                                 "receiver (zero path length); move it away")
            data[:, sl] = block
            bar.done(sl.stop - sl.start)
    for h in range(n_rx):
        data[h, :, n_valid[h]:] = 0
    return data


def _compressed_provenance(opts: SynthesisOptions, physics: Physics) -> dict:
    """How the echo reached the compressed domain: the response's taps (and the share of its energy
    dropped), or the raw route (nothing dropped: ``discarded_db`` None)."""
    resp = physics.response
    return {"window": opts.compressed, "level_db": opts.compressed_level_db,
            "route": "raw echo + matched filter" if physics.compress_raw else "taps", "taps": resp.taps,
            "discarded_db": None if physics.compress_raw else resp.discarded_db}


def simulate(scenario: Scenario, backend: str | None = None, stop_and_go: bool = False, snr_db: float | None = None,
             seed=None, precision: str = "single", progress: bool = True, spreading: bool | str = AUTO,
             occlusion=None, max_bytes: int | None = None, chunk_bytes: int = DEFAULT_CHUNK_BYTES,
             hull_occlusion: bool = True, reuse_tolerance: float = DEFAULT_REUSE_TOLERANCE,
             absorption: bool | str = AUTO, multipath: int | str = AUTO,
             intra_pulse: str = "moving", accumulation: str = "auto", compressed: bool | str = False,
             compressed_level_db: float = DEFAULT_LEVEL_DB, snr_reference: str = "echo") -> EchoData:
    """Synthesize the raw echoes of ``scenario`` (see the module docstring for the model).

    Parameters
    ----------
    scenario : Scenario with at least one target (``Scenario.targets``).
    backend : {"numpy", "opencl", "auto"} or None (the current default, :func:`clsas.use_backend`).
    stop_and_go : bool
        Evaluate every position at the emission time (for comparisons) instead of the exact
        non-stop-and-go delays.
    snr_db : float, optional
        Add white Gaussian noise at this SNR (definition in the module docstring); ``seed`` seeds it.
    snr_reference : {"echo", "record"}
        The signal power ``snr_db`` is taken over (:func:`add_noise`): "echo" (default) the mean
        |s|^2 over the samples where the noise-free echo is nonzero, "record" over every recorded
        sample (MATLAB's ``awgn(s, snr, "measured")`` on the whole record; one reading of Kiang &
        Kiang 2022's SNR). They differ by :func:`snr_offset_db`.
    precision : {"single", "double"}
        Accumulation precision of the OpenCL kernel (delays are always double). The returned
        samples are complex64 either way (DESIGN.md); :func:`synthesize` returns them in
        complex128 (the float64 reference).
    progress : bool
        Show tqdm progress bars over pulse blocks.
    spreading : bool or "auto"
        Include the spherical spreading 1 / (R1 R2) (R1, R2 the lengths of the two legs, unfolded
        for a bouncing path). "auto" (default): on when the scenario has a seafloor.
    absorption : bool or "auto"
        Include the absorption of the water (Francois & Garrison 1982 with the Medium's
        temperature, salinity, depth and pH) over the pulse's band, per path
        (:mod:`clsas.synthesis.propagation`). "auto" (default): on when the scenario has a seafloor.
    multipath : {0, 1, 2} or "auto"
        The most bounces a path may have off the sea surface (``Scenario.surface``: reflection
        -1, Rayleigh roughness loss) and the seabed's mean plane (``Scenario.seafloor``: its
        sediment's reflection coefficient): image sources, every path's delay exact. "auto"
        (default): 1 when the scenario has a surface or a seafloor, else 0.
    intra_pulse : {"moving", "all", "none"}
        Intra-pulse Doppler: the scatterer and the receivers keep moving while the pulse is
        emitted and received, so each fast-time sample has its own delay (the echo is
        time-scaled and Doppler-shifted, :mod:`clsas.synthesis.paths`). "moving" (default) for
        scatterers with a velocity, "all" for every path (stationary scatterers seen from the
        moving platform too), "none" for one delay per path (the pulse placed at its centre's
        delay: the stop-in-pulse model). Ignored with ``stop_and_go``.
    accumulation : {"auto", "direct", "grid"}
        How the raw records are made: "direct" adds each path's T fs samples; "grid" places each
        path as a fractional-delay impulse on a fast-time grid of 4 points a sample and filters
        each record once by the pulse (FFT), subtracting the smoothed pulse's tails path by path
        (:mod:`clsas.synthesis.echo.grid`: the same exact delays, the pulse band-limited; paths
        without intra-pulse Doppler, band envelopes within a second-order series). "auto"
        (default): "grid" for scenes of at least 100,000 paths a record where it applies.
    compressed : bool or str
        Synthesize straight into the range-compressed domain: the echo
        ``range_compress(simulate(...), window=W)`` would give (W = "none" for True, or the
        window named), each path's compressed point response written around its exact delay
        over the taps where it exceeds ``compressed_level_db`` re its peak
        (:mod:`clsas.synthesis.echo.compressed`). For large scenes (a seafloor's facets): the
        work per path is those taps instead of the whole pulse; where the taps would cost more
        than the pulse's samples, the raw echo is synthesized and range-compressed record by
        record instead (``provenance["compressed"]["route"]``). Not with ``snr_db`` (the noise is
        defined on raw samples).
    compressed_level_db : float
        dB in [-120, -10]: where the compressed response is cut (default -40).
    occlusion : None, array (n_rx, n_pulses, n_scatterers) or callable
        Factor per path (1 = seen, 0 = hidden); a callable ``occlusion(pulses: slice)`` returns
        the block (n_rx, len(pulses), n_scatterers), so that memory stays bounded. Mesh targets
        multiply it by their own path weights (hull visibility by Embree ray casting and the
        facets' angular law, :mod:`clsas.synthesis.occlusion`).
    hull_occlusion : bool
        Cast rays for the hull occlusion of mesh targets (False keeps only back-facing
        darkness and the angular law).
    reuse_tolerance : float
        rad: a facet's hull visibility is reused between pulses whose directions from it differ
        by at most this angle and whose bracketing casts agree (0 casts every ray;
        :class:`clsas.synthesis.occlusion.PathWeights`).
    max_bytes : int, optional
        Largest echo cube allowed (complex64; default the memory budget, :func:`clsas.memory_budget`);
        larger requests are refused before allocation.
    chunk_bytes : int
        Working memory per pulse block.

    Returns
    -------
    EchoData, raw (or with ``compressed`` range-compressed), complex64 (n_rx, n_pulses, n_samples). The recording
    window of receiver h starts at ``t0[h]`` (from the geometry: earliest echo minus T/2, to
    the latest plus T/2, unless ``Scenario.recording`` gives it); its samples beyond its own
    window length (``provenance["n_valid"]``) are zero.
    """
    max_bytes, chunk_bytes = check_arguments(scenario, snr_db, seed, max_bytes, chunk_bytes, reuse_tolerance, dict(
        stop_and_go=stop_and_go, progress=progress, hull_occlusion=hull_occlusion))
    for name, value in (("spreading", spreading), ("absorption", absorption)):
        auto_flag(f"simulate {name}", value)
    choice("simulate snr_reference", snr_reference, SNR_REFERENCES)
    if compressed is not False and snr_db is not None:
        raise ValueError(f"simulate snr_db: noise ({snr_db!r} dB) is defined on raw samples; with compressed="
                         f"{compressed!r} simulate the raw echo with noise and range_compress it instead")
    opts = SynthesisOptions(backend=backend, precision=precision, stop_and_go=stop_and_go, spreading=spreading,
                            absorption=absorption, multipath=multipath, intra_pulse=intra_pulse, accumulation=accumulation,
                            compressed=compressed, compressed_level_db=compressed_level_db,
                            hull_occlusion=hull_occlusion, reuse_tolerance=reuse_tolerance, max_bytes=max_bytes,
                            chunk_bytes=chunk_bytes, progress=progress)
    out = synthesize(scenario, opts, occlusion)
    data = out.data
    if snr_db is not None:
        add_noise(data, float(snr_db), seed, out.n_valid, reference=snr_reference)
    rx_tau, rx_pos = out.nodes
    n_rx = scenario.n_receivers
    return EchoData(
        data=data, eta=scenario.eta, t0=out.t0, fs=scenario.waveform.fs,
        tx_pos=scenario.tx_position(scenario.eta), rx_pos=rx_pos, rx_tau=np.tile(rx_tau, (n_rx, 1)),
        waveform=scenario.waveform, medium=scenario.medium, receivers=scenario.receiver_names,
        compressed=out.physics.response is not None,
        provenance={"algorithm": "clsas.simulate", "backend": opts.backend, "precision": opts.precision,
                    "stop_and_go": bool(opts.stop_and_go), "spreading": bool(out.physics.spreading),
                    "absorption": out.physics.absorption is not None,
                    "paths": [kind.name for kind in out.physics.kinds],
                    "intra_pulse": out.physics.intra_pulse if out.physics.doppler else "none", "snr_db": snr_db,
                    "accumulation": "direct" if out.physics.grid is None else "grid",
                    **({"snr_reference": snr_reference} if snr_db is not None else {}),
                    **({"compressed": _compressed_provenance(opts, out.physics)} if out.physics.response else {}),
                    "seed": seed if seed is None or isinstance(seed, int) else str(seed),
                    "n_scatterers": out.n_scatterers, "occlusion": occlusion is not None,
                    "hull_occlusion": bool(opts.hull_occlusion and needs_path_weights(scenario)),
                    **({"reuse_tolerance": opts.reuse_tolerance} if opts.hull_occlusion and has_meshes(scenario) else {}),
                    "window": out.origin, "n_valid": out.n_valid.tolist(),
                    "rx_node_error_m": out.node_error_m},
        scenario=scenario,
    )
