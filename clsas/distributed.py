"""Scale-out on Dask: echo synthesis over pulse blocks and back-projection over image tiles.

Each task is one call of the single-process function on a part of the work, run by a
``dask.distributed.Client`` (a ``LocalCluster`` on one machine, or a scheduler and workers on
many); the client assembles the parts and, given ``out=``, saves the result with
:func:`clsas.save` (a path ending in ``.zarr`` gives a chunked zarr store)::

    from dask.distributed import Client
    client = Client(n_workers=2, threads_per_worker=1)      # or Client("tcp://scheduler:8786")
    echo = clsas.distributed.simulate(scene, client, out="echo.zarr")
    image = clsas.distributed.backproject(clsas.range_compress(echo), grid, client, out="image.zarr")

Agreement with one process (measured in tests/test_distributed.py, 2 workers, 15 receivers):

- :func:`simulate`: each pulse block is simulated with the whole run's recording window (the
  scenario's ``Recording``, or one derived on the workers from every path's delay, as
  :func:`clsas.simulate` derives it), so the blocks line up; a block's emission times are its
  own start + k / prf (within 1e-15 s of one process's). Noise is added on the client to the
  assembled cube exactly as :func:`clsas.simulate` adds it. NumPy backend: bit for bit; OpenCL:
  within 1.0e-7 of the peak (float32 rounding).
- :func:`backproject`: each task images a band of grid rows with all pulses and receivers.
  NumPy backend: bit for bit. OpenCL: each band plans its own tiles (float32 geometry relative
  to a tile reference, within the kernel's 2e-3 rad PHASE_BUDGET), so pixels differ from one
  process by up to 1.3e-4 of the peak.

The assembled result is held by the client (the echo cube or the image must fit in its memory);
the workers hold one block each.
"""

from __future__ import annotations

import logging

import numpy as np

from .data import EchoData, Grid, Image
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


def _block_extent(scenario: Scenario, backend, stop_and_go: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per receiver, the echo-centre extents in whole samples (floor of the earliest, floor of the
    latest + 1), rounded as :func:`clsas.simulate` rounds them (``sample_extents``)."""
    from .simulate import delays

    u = delays(scenario, backend=backend, stop_and_go=stop_and_go) * scenario.waveform.fs  # (H, P, N) samples
    return np.floor(u.min(axis=(1, 2))), np.floor(u.max(axis=(1, 2))) + 1


def recording_window(scenario: Scenario, client, pulses_per_task: int = 64, backend=None,
                     stop_and_go: bool = False) -> Recording:
    """The recording window of the whole run as :func:`clsas.simulate` derives it: per receiver,
    from the earliest echo centre minus half the pulse to the latest plus half the pulse, in
    whole samples (the delays computed on the workers, a pulse block a task)."""
    _check_client(client)
    wf = scenario.waveform
    futures = [client.submit(_block_extent, pulse_block(scenario, a, b), backend, stop_and_go, pure=False)
               for a, b in _blocks(scenario.eta.size, pulses_per_task)]
    extents = client.gather(futures)
    lo = np.min([e[0] for e in extents], axis=0) / wf.fs  # s, whole samples
    hi = np.max([e[1] for e in extents], axis=0) / wf.fs
    first = np.floor((lo - 0.5 * wf.duration) * wf.fs)  # the arithmetic of simulate's own window
    last = np.ceil((hi + 0.5 * wf.duration) * wf.fs)
    return Recording(t0=first / wf.fs, n_samples=(last - first + 1).astype(np.int64))


def _simulate_block(scenario: Scenario, kwargs: dict) -> EchoData:
    from .simulate import simulate as simulate_one

    return simulate_one(scenario, progress=False, **kwargs)


def simulate(scenario: Scenario, client, pulses_per_task: int = 64, snr_db: float | None = None, seed=None,
             out=None, **kwargs) -> EchoData:
    """:func:`clsas.simulate` over blocks of ``pulses_per_task`` pulses on the Dask ``client``.

    ``kwargs`` go to :func:`clsas.simulate` (``backend``, ``stop_and_go``, ``spreading``, ...).
    Noise (``snr_db``, ``seed``) is added on the client to the assembled cube. With ``out`` the
    echo is saved there (``.zarr`` or ``.nc``). Returns the EchoData.
    """
    from .simulate.echo import add_noise
    from .simulate.window import receiver_nodes

    _check_client(client)
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    blocks = _blocks(scenario.eta.size, pulses_per_task)
    given = scenario
    with stage("distributed echo synthesis", f"{scenario.n_receivers} receivers x {scenario.eta.size} pulses in "
               f"{len(blocks)} tasks"):
        if scenario.recording is None:
            scenario = scenario.replace(recording=recording_window(scenario, client, pulses_per_task,
                                                                   kwargs.get("backend"), kwargs.get("stop_and_go", False)))
        futures = [client.submit(_simulate_block, pulse_block(scenario, a, b), kwargs, pure=False) for a, b in blocks]
        parts = client.gather(futures)
    data = np.concatenate([p.data for p in parts], axis=1)
    if all(np.array_equal(p.rx_tau, parts[0].rx_tau) for p in parts):
        rx_tau, rx_pos = parts[0].rx_tau, np.concatenate([p.rx_pos for p in parts], axis=1)
    else:  # blocks spaced their nodes differently: one set over the longest span for the whole run
        tau_hi = max(float(p.rx_tau[0, -1]) for p in parts)
        nodes = receiver_nodes(scenario, scenario.eta, tau_hi, strict=False)
        rx_tau, rx_pos = np.tile(nodes[0], (scenario.n_receivers, 1)), nodes[1]
    n_valid = np.asarray(scenario.recording.for_receivers(scenario.n_receivers)[1])
    if snr_db is not None:
        add_noise(data, float(snr_db), seed, n_valid)
    provenance = dict(parts[0].provenance, snr_db=snr_db, seed=seed if seed is None or isinstance(seed, int) else str(seed),
                      distributed={"tasks": len(blocks), "pulses_per_task": int(pulses_per_task)})
    echo = parts[0].replace(data=data, eta=scenario.eta, tx_pos=np.concatenate([p.tx_pos for p in parts]),
                            rx_pos=rx_pos, rx_tau=rx_tau, provenance=provenance, scenario=given)
    if out is not None:
        from .io import save

        save(echo, out)
    return echo


def _backproject_band(echo, grid: Grid, kwargs: dict) -> np.ndarray:
    from .image.backprojection import backproject as backproject_one

    image = backproject_one(echo, grid, progress=False, **kwargs)
    return image.data, image.provenance


def grid_band(grid: Grid, first: int, stop: int) -> Grid:
    """Rows ``first`` .. ``stop - 1`` (along the grid's first dim) as a Grid of their own."""
    axes = dict(grid.axes)
    axes[grid.dims[0]] = grid.axes[grid.dims[0]][first:stop]
    return Grid(grid.positions[first:stop], grid.dims, axes)


def backproject(echo: EchoData, grid: Grid, client, rows_per_task: int | None = None, out=None, **kwargs) -> Image:
    """:func:`clsas.backproject` over bands of grid rows on the Dask ``client``.

    The echo is sent to every worker once; ``rows_per_task`` (default: about 2^16 pixels a
    task) sets the bands. ``kwargs`` go to :func:`clsas.backproject`. With ``out`` the image is
    saved there. Returns the Image (the grid's dims, axes and positions).
    """
    _check_client(client)
    if not isinstance(echo, EchoData) or not isinstance(grid, Grid):
        raise TypeError("backproject takes an EchoData and a Grid")
    n_rows = grid.shape[0]
    per_row = max(1, grid.size // n_rows)
    rows = rows_per_task if rows_per_task is not None else max(1, 2**16 // per_row)
    bands = _blocks(n_rows, rows)
    with stage("distributed back-projection", f"{grid.size} pixels x {echo.n_rx} receivers x {echo.n_pulses} pulses "
               f"in {len(bands)} tasks"):
        shared = client.scatter(echo, broadcast=True)
        futures = [client.submit(_backproject_band, shared, grid_band(grid, a, b), kwargs, pure=False) for a, b in bands]
        parts = client.gather(futures)
    provenance = dict(parts[0][1], distributed={"tasks": len(bands), "rows_per_task": int(rows)})
    if "exact_fallback_blocks" in provenance:
        provenance["exact_fallback_blocks"] = int(sum(p[1]["exact_fallback_blocks"] for p in parts))
    image = Image(data=np.concatenate([p[0] for p in parts], axis=0), dims=grid.dims, axes=grid.axes,
                  positions=grid.positions, provenance=provenance)
    if out is not None:
        from .io import save

        save(image, out)
    return image
