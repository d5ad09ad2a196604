"""Scale-out on Dask: echo synthesis over pulse blocks and back-projection over image tiles.

Each task is one call of the single-process function on a part of the work, run by a
``dask.distributed.Client`` (a ``LocalCluster`` on one machine, or a scheduler and workers on
many)::

    from dask.distributed import Client
    client = Client(n_workers=2, threads_per_worker=1)      # or Client("tcp://scheduler:8786")
    echo = clsas.distributed.simulate(scene, client, out="echo.zarr")
    image = clsas.distributed.backproject(clsas.range_compress(echo), grid, client, out="image.zarr")

With ``out`` ending in ``.zarr`` the workers write their own parts (pulse blocks, image row
bands) into the store, chunked along those parts, and the client writes only the metadata and
the geometry; ``gather=False`` then returns the store's Path without reading it back, so the
client never holds the echo cube or the image. The store must be reachable from every worker
(one machine, or a shared folder). It is written under a temporary name beside ``out`` and
renamed when complete. Other ``out`` names (``.nc``) are written by the client from the
gathered result (HDF5 files take one writer).

Agreement with one process (measured in tests/test_distributed.py, 2 workers, 15 receivers):

- :func:`simulate`: the recording window and the receiver nodes follow from every path's delay
  (computed on the workers, a pulse block a task) exactly as :func:`clsas.simulate` derives
  them, so the blocks line up and the geometry (``eta``, ``tx_pos``, ``rx_tau``, ``rx_pos``)
  is one process's. Noise: each block's signal power is summed per pulse in float64 on its
  worker; the client adds the noise block by block (the random stream of :func:`clsas.simulate`),
  in the store when there is one. NumPy backend: echo and geometry bit for bit, noise included;
  OpenCL: samples within 1.0e-7 of the peak (float32 rounding).
- :func:`backproject`: each task images a band of grid rows with all pulses and receivers.
  NumPy backend: bit for bit. OpenCL: each band plans its own tiles (float32 geometry relative
  to a tile reference, within the kernel's 2e-3 rad PHASE_BUDGET), so pixels differ from one
  process by up to 1.3e-4 of the peak.
"""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path

import numpy as np

from .model import EchoData, Grid, Image
from .progress import stage
from .scene.scenario import PulseSchedule, Recording, Scenario

log = logging.getLogger("clsas")


def _blocks(n: int, size: int) -> list[tuple[int, int]]:
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
        raise ValueError(f"the block size must be an integer >= 1, got {size!r}")
    return [(s, min(s + int(size), n)) for s in range(0, n, int(size))]


def _check_client(client) -> None:
    if not hasattr(client, "submit") or not hasattr(client, "gather"):
        raise TypeError(f"client must be a dask.distributed.Client, got {type(client).__name__}")


def pulse_block(scenario: Scenario, first: int, stop: int) -> Scenario:
    """The scenario of pulses ``first`` .. ``stop - 1`` alone (same emission times)."""
    eta = scenario.eta
    schedule = PulseSchedule(prf=scenario.schedule.prf, n_pulses=stop - first, start=float(eta[first]))
    return scenario.replace(schedule=schedule)


def _block_extent(scenario: Scenario, backend, stop_and_go: bool, multipath) -> tuple[np.ndarray, np.ndarray]:
    """Per receiver, the echo-centre extents in whole samples (floor of the earliest, floor of the
    latest + 1) over every path kind :func:`clsas.simulate` synthesizes at ``multipath`` and the
    scatterers each pulse hears: simulate's own pass A (:func:`clsas.synthesis.echo.window_extents`;
    every facet's delays made the window wider than simulate's, and it changed with the blocks)."""
    from .synthesis import SynthesisOptions
    from .synthesis.echo import window_extents

    return window_extents(scenario, SynthesisOptions(backend=backend, stop_and_go=stop_and_go, multipath=multipath))


def _extents(scenario: Scenario, client, pulses_per_task: int, backend, stop_and_go: bool, multipath="auto"):
    """Earliest and latest echo centre per receiver over the whole run, s (whole samples), and
    which pulse blocks (:func:`_blocks`) hear anything (a block whose beam reaches none of the
    seafloor and that has no target hears nothing: its echo is zeros)."""
    from .synthesis import SynthesisOptions

    multipath = SynthesisOptions(multipath=multipath).multipath  # checked here, before any task
    futures = [client.submit(_block_extent, pulse_block(scenario, a, b), backend, stop_and_go, multipath, pure=False)
               for a, b in _blocks(scenario.eta.size, pulses_per_task)]
    extents = _gather(client, futures)
    hears = [bool(np.any(np.isfinite(e[0]))) for e in extents]
    if not any(hears):
        from .synthesis.echo.pipeline import nothing_heard

        raise nothing_heard(scenario)
    fs = scenario.waveform.fs
    return np.min([e[0] for e in extents], axis=0) / fs, np.max([e[1] for e in extents], axis=0) / fs, hears


def _window_of(scenario: Scenario, lo: np.ndarray, hi: np.ndarray) -> Recording:
    wf = scenario.waveform
    first = np.floor((lo - 0.5 * wf.duration) * wf.fs)  # the arithmetic of simulate's own window
    last = np.ceil((hi + 0.5 * wf.duration) * wf.fs)
    return Recording(t0=first / wf.fs, n_samples=(last - first + 1).astype(np.int64))


def recording_window(scenario: Scenario, client, pulses_per_task: int = 64, backend=None,
                     stop_and_go: bool = False, multipath="auto") -> Recording:
    """The recording window of the whole run as :func:`clsas.simulate` derives it: per receiver,
    from the earliest echo centre minus half the pulse to the latest plus half the pulse over
    every path (``multipath`` as :func:`clsas.simulate` takes it: the bounces off the sea
    surface and the seabed too), in whole samples (the delays computed on the workers, a pulse
    block a task)."""
    _check_client(client)
    return _window_of(scenario, *_extents(scenario, client, pulses_per_task, backend, stop_and_go, multipath)[:2])


def _geometry(scenario: Scenario, hi: np.ndarray):
    """(rx_tau (n_rx, K), rx_pos (n_rx, P, K, 3), largest interpolation error m): the receiver
    nodes :func:`clsas.simulate` places over the recording window (``hi``: latest echo centre
    per receiver, s)."""
    from .synthesis.window import node_span, receiver_nodes

    wf = scenario.waveform
    span = node_span(scenario, scenario.eta, float(hi.max()) + 0.5 * wf.duration + 2 / wf.fs)
    taus, positions, _, error = receiver_nodes(scenario, scenario.eta, span, strict=False)
    return np.tile(taus, (scenario.n_receivers, 1)), positions, float(error)


def _simulate_block(scenario: Scenario, kwargs: dict, store: str | None, first: int, n_valid) -> tuple:
    """One pulse block: its echo (or, with ``store``, written into the store's region and
    dropped), its signal power per pulse (for the noise) and its provenance."""
    from .synthesis import simulate as simulate_one
    from .synthesis.echo import signal_power

    echo = simulate_one(scenario, progress=False, **kwargs)
    power = signal_power(echo.data, n_valid)
    if store is None:
        return echo, power, echo.provenance
    from .io.files.write import zarr_array

    zarr_array(Path(store), "echo")[:, first:first + echo.n_pulses] = echo.data
    return None, power, echo.provenance


def _silent_block(scenario: Scenario, first: int, stop: int, n_valid: np.ndarray, store: str | None) -> tuple:
    """A pulse block that hears nothing (:func:`_extents`), as :func:`_simulate_block` returns one:
    zeros in the window (with ``store``, written into the store's region: every chunk must be
    written), zero signal power, no provenance of its own."""
    n_rx, n_p = scenario.n_receivers, stop - first
    data = np.zeros((n_rx, n_p, int(np.max(n_valid))), np.complex64)
    if store is not None:
        from .io.files.write import zarr_array

        zarr_array(Path(store), "echo")[:, first:stop] = data
        data = None
    return data, (np.zeros((n_rx, n_p)), np.zeros((n_rx, n_p), np.int64)), None


def simulate(scenario: Scenario, client, pulses_per_task: int = 64, snr_db: float | None = None, seed=None,
             out=None, gather: bool = True, **kwargs):
    """:func:`clsas.simulate` over blocks of ``pulses_per_task`` pulses on the Dask ``client``.

    ``kwargs`` go to :func:`clsas.simulate` (``backend``, ``stop_and_go``, ``spreading``, ...).
    With ``out`` ending in ``.zarr`` each worker writes its pulse blocks into the store (see the
    module docstring); other ``out`` names are written from the gathered echo. Noise
    (``snr_db``, ``seed``) is added by the client as :func:`clsas.simulate` adds it. Returns the
    EchoData, or (``gather=False``, with a zarr ``out``) the store's Path.
    """
    from .synthesis.echo import add_noise

    _check_client(client)
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    store = _store(out, gather, "echo")
    blocks = _blocks(scenario.eta.size, pulses_per_task)
    backend, stop_and_go = kwargs.get("backend"), kwargs.get("stop_and_go", False)
    given = scenario
    with _temporary(store) as tmp:
        with stage("distributed echo synthesis", f"{scenario.n_receivers} receivers x {scenario.eta.size} pulses in "
                   f"{len(blocks)} tasks" + (f", written by the workers to {store}" if store else "")):
            lo, hi, hears = _extents(scenario, client, pulses_per_task, backend, stop_and_go,
                                     kwargs.get("multipath", "auto"))
            if scenario.recording is None:
                scenario = scenario.replace(recording=_window_of(scenario, lo, hi))
            rx_tau, rx_pos, node_error = _geometry(scenario, hi)
            t0, n_valid = (np.asarray(a) for a in scenario.recording.for_receivers(scenario.n_receivers))
            if store is not None:
                head = EchoData(data=np.broadcast_to(np.complex64(0), (scenario.n_receivers, scenario.eta.size,
                                                                       int(n_valid.max()))),
                                eta=scenario.eta, t0=t0, fs=scenario.waveform.fs,
                                tx_pos=scenario.tx_position(scenario.eta), rx_pos=rx_pos, rx_tau=rx_tau,
                                waveform=scenario.waveform, medium=scenario.medium,
                                receivers=scenario.receiver_names, scenario=given)
                _zarr_template(head, tmp, "echo", (1, int(pulses_per_task)))
            futures = [client.submit(_simulate_block, pulse_block(scenario, a, b), kwargs,
                                     None if tmp is None else str(tmp), a, n_valid, pure=False)
                       for (a, b), heard in zip(blocks, hears) if heard]
            heard_parts = iter(_gather(client, futures))
            parts = [next(heard_parts) if heard else _silent_block(scenario, a, b, n_valid, None if tmp is None else str(tmp))
                     for (a, b), heard in zip(blocks, hears)]
        power = (np.concatenate([p[1][0] for p in parts], axis=1), np.concatenate([p[1][1] for p in parts], axis=1))
        provenance = dict(next(p[2] for p in parts if p[2] is not None), snr_db=snr_db,
                          seed=seed if seed is None or isinstance(seed, int) else str(seed),
                          distributed={"tasks": len(blocks), "pulses_per_task": int(pulses_per_task),
                                       "written_by": "workers" if store else "client"},
                          rx_node_error_m=node_error)
        if store is not None:
            from .io.files.write import zarr_array

            if snr_db is not None:
                add_noise(zarr_array(tmp, "echo"), float(snr_db), seed, n_valid, power=power)
            _finish_store(tmp, store, provenance)
    if store is not None:
        if not gather:
            return store
        from .io import load

        return load(store)
    data = np.concatenate([p[0] if isinstance(p[0], np.ndarray) else p[0].data for p in parts], axis=1)
    if snr_db is not None:
        add_noise(data, float(snr_db), seed, n_valid, power=power)
    echo = next(p[0] for p in parts if not isinstance(p[0], np.ndarray)).replace(data=data, eta=scenario.eta, tx_pos=scenario.tx_position(scenario.eta), rx_pos=rx_pos,
                               rx_tau=rx_tau, provenance=provenance, scenario=given)
    if out is not None:
        from .io import save

        save(echo, out)
    return echo


def _gather(client, futures) -> list:
    """The tasks' results; when one fails (or the gather is interrupted), the others are
    cancelled before the error goes on, so that none keeps writing into a store the failure is
    about to delete (nor wastes the workers' time)."""
    try:
        return client.gather(futures)
    except BaseException:
        client.cancel(futures)
        raise


def _store(out, gather: bool, what: str) -> Path | None:
    """The zarr store ``out`` names, checked before any work (None for another or no ``out``)."""
    if not isinstance(gather, bool):
        raise TypeError(f"gather: must be True or False, got {gather!r}")
    if out is None:
        if not gather:
            raise ValueError(f"gather=False needs out=... ending in .zarr (the workers write the {what} there)")
        return None
    from .io.files import check_target

    path = check_target("out", out)
    if path.suffix != ".zarr":
        if not gather:
            raise ValueError(f"gather=False needs out=... ending in .zarr (the workers write the {what} there)")
        return None
    return path


@contextlib.contextmanager
def _temporary(store: Path | None):
    """The temporary store beside ``store`` the workers write (deleted on failure), or None."""
    if store is None:
        yield None
        return
    from .io.files.target import temporary

    with temporary(store) as tmp:
        yield tmp


def _zarr_template(head, tmp: Path, name: str, part_chunks: tuple) -> None:
    """Write ``head``'s dataset to the store ``tmp``, with the big variable ``name`` as metadata
    only (chunks: ``part_chunks`` on its leading axes, the rest whole, cut to about
    :data:`clsas.io.CHUNK_BYTES`), for the workers to fill."""
    import dask.array as da

    from .io.dataset import to_xarray
    from .io.files.write import CHUNK_BYTES, encoding as file_encoding

    ds = to_xarray(head)
    var = ds[name]
    chunks = list(part_chunks) + list(var.shape[len(part_chunks):])
    per_row = var.dtype.itemsize * int(np.prod(chunks[:-1]))
    chunks[-1] = int(max(1, min(chunks[-1], CHUNK_BYTES // max(per_row, 1))))
    chunks = tuple(int(min(c, s)) if s else 1 for c, s in zip(chunks, var.shape))
    ds[name] = var.copy(data=da.zeros(var.shape, chunks=chunks, dtype=var.dtype))
    encoding = file_encoding(ds, True, 1)
    encoding[name]["chunks"] = chunks
    ds.to_zarr(tmp, mode="w-", compute=False, encoding=encoding, consolidated=True, zarr_format=2)


def _finish_store(tmp: Path, store: Path, provenance: dict) -> None:
    """Record the provenance, consolidate the metadata, check every chunk was written and move
    the store into place with one rename (:func:`clsas.io.files.target.replace`)."""
    import zarr

    from .io.dataset import to_json
    from .io.files.read import check_chunks
    from .io.files.target import replace

    group = zarr.open_group(str(tmp), mode="r+")
    group.attrs["provenance"] = to_json(provenance)
    zarr.consolidate_metadata(str(tmp))
    check_chunks(tmp)
    replace(tmp, store)
    log.info("the workers wrote %s", store)


def _backproject_band(echo, grid: Grid, kwargs: dict, store: str | None, first: int):
    from .image.backprojection import backproject as backproject_one

    image = backproject_one(echo, grid, progress=False, **kwargs)
    if store is None:
        return image.data, image.provenance
    from .io.files.write import zarr_array

    zarr_array(Path(store), "image")[first:first + image.data.shape[0]] = image.data
    return None, image.provenance


def grid_band(grid: Grid, first: int, stop: int) -> Grid:
    """Rows ``first`` .. ``stop - 1`` (along the grid's first dim) as a Grid of their own."""
    axes = dict(grid.axes)
    axes[grid.dims[0]] = grid.axes[grid.dims[0]][first:stop]
    return Grid(grid.positions[first:stop], grid.dims, axes)


def backproject(echo: EchoData, grid: Grid, client, rows_per_task: int | None = None, out=None, gather: bool = True,
                **kwargs):
    """:func:`clsas.backproject` over bands of grid rows on the Dask ``client``.

    The echo is sent to every worker once; ``rows_per_task`` (default: about 2^16 pixels a
    task) sets the bands. ``kwargs`` go to :func:`clsas.backproject`. With ``out`` ending in
    ``.zarr`` each worker writes its bands into the store; other ``out`` names are written
    from the gathered image. Returns the Image (the grid's dims, axes and positions), or
    (``gather=False``, with a zarr ``out``) the store's Path.
    """
    _check_client(client)
    if not isinstance(echo, EchoData) or not isinstance(grid, Grid):
        raise TypeError("backproject takes an EchoData and a Grid")
    store = _store(out, gather, "image")
    n_rows = grid.shape[0]
    per_row = max(1, grid.size // n_rows)
    rows = rows_per_task if rows_per_task is not None else max(1, 2**16 // per_row)
    bands = _blocks(n_rows, rows)
    with _temporary(store) as tmp:
        if store is not None:
            head = Image(data=np.broadcast_to(np.complex64(0), grid.shape), dims=grid.dims, axes=grid.axes,
                         positions=grid.positions)
            _zarr_template(head, tmp, "image", (int(rows),))
        with stage("distributed back-projection", f"{grid.size} pixels x {echo.n_rx} receivers x {echo.n_pulses} "
                   f"pulses in {len(bands)} tasks" + (f", written by the workers to {store}" if store else "")):
            shared = client.scatter(echo, broadcast=True)
            futures = [client.submit(_backproject_band, shared, grid_band(grid, a, b), kwargs,
                                     None if tmp is None else str(tmp), a, pure=False) for a, b in bands]
            parts = _gather(client, futures)
        provenance = dict(parts[0][1], distributed={"tasks": len(bands), "rows_per_task": int(rows),
                                                    "written_by": "workers" if store else "client"})
        if "exact_fallback_blocks" in provenance:
            provenance["exact_fallback_blocks"] = int(sum(p[1]["exact_fallback_blocks"] for p in parts))
        if store is not None:
            _finish_store(tmp, store, provenance)
    if store is not None:
        if not gather:
            return store
        from .io import load

        return load(store)
    image = Image(data=np.concatenate([p[0] for p in parts], axis=0), dims=grid.dims, axes=grid.axes,
                  positions=grid.positions, provenance=provenance)
    if out is not None:
        from .io import save

        save(image, out)
    return image
