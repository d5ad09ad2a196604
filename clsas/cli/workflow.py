"""``clsas simulate``, ``clsas image`` and ``clsas plot``: the file-to-file workflow.

    clsas simulate huang2022 -o echo.nc --pulses 128 --snr 20 --seed 1
    clsas image echo.nc --algorithm omegak -o image.nc --png image.png
    clsas plot image.nc -o image.png

Every output is checked before any work (:func:`._common.check_outputs`): a known suffix, an
existing folder, never the input, and an existing file only with ``--overwrite``. ``simulate``
also checks, before the echo cube is allocated, that the cube, the synthesis's working memory
and the save fit the memory budget (``CLSAS_MEMORY_BUDGET``).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ._common import UsageError, add_overwrite_argument, check_outputs, parse_grid, write_png

log = logging.getLogger("clsas")

ALGORITHMS = ("bp", "ffbp", "omegak", "rda", "csa", "ncs")
STRIP_IMAGERS = ("omegak", "rda", "csa", "ncs")  # straight-track, frequency-domain
WINDOWS = ("none", "hamming", "taylor", "kaiser")
DEFAULT_MAX_PIXELS = 512 * 512


def add_simulate_arguments(parser) -> None:
    from ..scene import presets

    parser.add_argument("scene", metavar="SCENE.toml|PRESET",
                        help="a scenario file (TOML, docs/scenario-toml.md) or a paper's point scene: "
                             f"{', '.join(sorted(presets.POINT_LAYOUTS))}")
    parser.add_argument("-o", "--out", required=True, help="output file: .nc (NetCDF4) or .zarr")
    parser.add_argument("--pulses", type=int, default=None,
                        help="number of pulses (default: the scenario's), keeping its PRF and centre")
    parser.add_argument("--snr", type=float, default=None, help="add complex white noise at this SNR, dB")
    parser.add_argument("--seed", type=int, default=None, help="noise seed (repeatable runs)")
    parser.add_argument("--backend", choices=("auto", "opencl", "numpy"), default=None,
                        help="where the kernels run (default: CLSAS_BACKEND or auto)")
    add_overwrite_argument(parser)


def load_scene(name: str, pulses: int | None):
    """The Scenario of a TOML file or a preset name; ``pulses`` replaces the pulse count, keeping
    the PRF and the schedule's centre (or its start, when the file gives one)."""
    from ..scene import presets
    from ..scene.scenario import PulseSchedule
    from ..io import load_scenario

    if pulses is not None and pulses < 1:
        raise UsageError(f"--pulses must be >= 1, got {pulses}")
    if name.endswith(".toml"):
        scene = load_scenario(name)
        if pulses is not None:
            old = scene.schedule
            scene = scene.replace(schedule=PulseSchedule(prf=old.prf, n_pulses=pulses, start=old.start))
        return scene
    if name not in presets.POINT_LAYOUTS:
        raise UsageError(f"unknown preset {name!r}; give a scenario file (.toml) or one of "
                         f"{', '.join(sorted(presets.POINT_LAYOUTS))}")
    return presets.point_scene(name, n_pulses=pulses)


def run_simulate(args) -> int:
    from .. import budget, io
    from ..synthesis import simulate
    from ..synthesis.echo.options import DEFAULT_CHUNK_BYTES

    out = check_outputs({"-o": args.out}, inputs=(args.scene,), overwrite=args.overwrite)["-o"]
    scene = load_scene(args.scene, args.pulses)
    if not scene.targets:
        raise UsageError(f"{args.scene}: the scenario has no targets ([[targets]]): its echoes would be zero")
    allowed = budget.memory_budget()
    cube = allowed - DEFAULT_CHUNK_BYTES - io.files.SAVE_WORKING_BYTES  # what is left for the echo itself
    if cube <= 0:
        raise UsageError(f"the memory budget ({allowed} bytes) leaves nothing for the echo; raise CLSAS_MEMORY_BUDGET")
    t = time.perf_counter()
    try:
        echo = simulate(scene, snr_db=args.snr, seed=args.seed, backend=args.backend, progress=args.progress,
                        max_bytes=cube)
    except ValueError as err:
        if "max_bytes" not in str(err):
            raise
        raise UsageError(f"{err} [here max_bytes is the memory budget of {allowed / 2**30:.3g} GiB less the "
                         "synthesis's and the save's working memory: lower --pulses or raise CLSAS_MEMORY_BUDGET]") from None
    took = time.perf_counter() - t
    path = io.save(echo, out)
    print(f"{args.scene}: {echo.n_rx} receivers x {echo.n_pulses} pulses x {echo.n_samples} samples "
          f"simulated in {took:.1f} s -> {path} ({_size(path) / 2**20:.1f} MiB)")
    return 0


def add_image_arguments(parser) -> None:
    parser.add_argument("echo", metavar="ECHO", help="an echo file written by `clsas simulate` or clsas.save")
    parser.add_argument("--algorithm", "-a", choices=ALGORITHMS, default="bp",
                        help="bp: back-projection (any geometry); ffbp: fast factorised back-projection; "
                             "omegak (wavenumber), rda (range-Doppler), csa (chirp scaling), ncs (nonlinear chirp "
                             "scaling): straight-track frequency-domain imagers (several receivers are first merged "
                             "by PCA)")
    parser.add_argument("--grid", default=None,
                        help="bp and ffbp: X0:X1:DX,Y0:Y1:DY,Z in metres (across track, along track, plane height); "
                             "default: the recorded ranges and the track's span at the track's depth, "
                             f"at most {DEFAULT_MAX_PIXELS} pixels")
    parser.add_argument("--window", default=None, choices=WINDOWS,
                        help="weighting (default none): bp and ffbp: the range compression's (raw echoes only); "
                             "omegak: the processed band in both wavenumbers (the range compression unweighted); "
                             "rda, csa, ncs: the processed Doppler band, and the range compression's for raw echoes")
    parser.add_argument("--elements", default=None, metavar="LTX,LRX",
                        help="omegak/rda/csa/ncs: along-track element lengths, m (band limit and pattern deconvolution); "
                             "default: those of the scenario stored in the echo file, if any")
    parser.add_argument("-o", "--out", default=None, help="image file (.nc or .zarr)")
    parser.add_argument("--png", default=None, help="also write a picture of the image with its cuts")
    parser.add_argument("--floor", type=float, default=-50.0, help="picture floor, dB (default -50)")
    parser.add_argument("--backend", choices=("auto", "opencl", "numpy"), default=None)
    add_overwrite_argument(parser)


def default_grid(echo, max_pixels: int = DEFAULT_MAX_PIXELS):
    """The horizontal plane at the track's depth covering the recorded slant ranges (receiver
    0) across track and the transmitter's span along track, at a quarter of the range
    resolution, coarsened evenly until it has at most ``max_pixels`` pixels."""
    from ..model import Grid

    c = echo.medium.sound_speed
    track = echo.tx_pos
    r0 = c * echo.t0[0] / 2
    r1 = c * (echo.t0[0] + (echo.n_samples - 1) / echo.fs) / 2
    x_track, z = float(np.mean(track[:, 0])), float(np.mean(track[:, 2]))
    y0, y1 = float(track[:, 1].min()), float(track[:, 1].max())
    step = c / (2 * echo.waveform.bandwidth) / 4
    nx = max(2, int((r1 - r0) / step))
    ny = max(2, int((y1 - y0) / step))
    scale = max(1.0, np.sqrt(nx * ny / max_pixels))
    nx, ny = max(2, int(nx / scale)), max(2, int(ny / scale))
    return Grid.plane(np.linspace(x_track + r0, x_track + r1, nx), np.linspace(y0, y1, ny), z)


def _parse_elements(text):
    """--elements LTX,LRX (m, both finite and > 0), or None."""
    if text is None:
        return None
    try:
        ltx, lrx = (float(v) for v in text.split(","))
    except ValueError:
        raise UsageError(f"--elements: expected LTX,LRX in metres, got {text!r}") from None
    if not (np.isfinite([ltx, lrx]).all() and ltx > 0 and lrx > 0):
        raise UsageError(f"--elements: the lengths must be finite and > 0 m, got {text!r}")
    return ltx, lrx


def _elements(given, echo):
    """--elements (parsed), else the stored scenario's transmitter and longest receiver (both directive)."""
    if given is not None:
        return given
    array = echo.scenario.array if echo.scenario is not None else None
    if array is None or array.n_receivers == 0 or array.tx_length <= 0 or array.rx_length.min() <= 0:
        return None
    print(f"elements from the file's scenario: L_tx = {array.tx_length:g} m, L_rx = {array.rx_length.max():g} m")
    return float(array.tx_length), float(array.rx_length.max())


def run_image(args) -> int:
    from .. import io
    from ..model import EchoData
    from ..image import backproject, range_compress
    from ..image.csa import chirp_scaling
    from ..image.ffbp import ffbp
    from ..image.multireceiver import pca_record
    from ..image.ncs import nonlinear_chirp_scaling
    from ..image.omegak import omega_k
    from ..image.rda import range_doppler

    if args.out is None and args.png is None:
        raise UsageError("give -o IMAGE.nc and/or --png PICTURE.png: nothing would be written")
    outputs = check_outputs({"-o": args.out}, {"--png": args.png}, inputs=(args.echo,), overwrite=args.overwrite)
    _check_floor(args.floor)
    strip = args.algorithm in STRIP_IMAGERS
    if args.grid and strip:
        raise UsageError("--grid applies to --algorithm bp and ffbp only (the frequency-domain imagers have their own grid)")
    if args.elements is not None and not strip:
        raise UsageError(f"--elements applies to --algorithm {', '.join(STRIP_IMAGERS)} only (bp and ffbp have no band "
                         "limit or pattern deconvolution)")
    grid = parse_grid(args.grid) if args.grid else None
    elements = _parse_elements(args.elements)
    echo = io.load(args.echo)
    if not isinstance(echo, EchoData):
        raise UsageError(f"{args.echo} holds an image, not echoes; `clsas plot` shows it")
    t = time.perf_counter()
    if not echo.compressed:  # omega-k weights range in its own band: the compression then stays unweighted
        echo = range_compress(echo, window="none" if args.algorithm == "omegak" else args.window or "none")
    elif args.window and not strip:
        raise UsageError(f"{args.echo} is already range-compressed; --window applies to raw echoes with "
                         f"--algorithm {args.algorithm}")
    if not strip:
        grid = grid if grid is not None else default_grid(echo)
        what = f"{args.algorithm} onto {grid.shape[0]} x {grid.shape[1]} pixels"
        imager = backproject if args.algorithm == "bp" else ffbp
        image = imager(echo, grid, backend=args.backend, progress=args.progress)
    else:
        record = pca_record(echo, backend=args.backend) if echo.n_rx > 1 else echo
        imager = {"omegak": omega_k, "rda": range_doppler, "csa": chirp_scaling, "ncs": nonlinear_chirp_scaling}[
            args.algorithm]
        image = imager(record, elements=_elements(elements, echo), window=args.window or "none",
                       backend=args.backend)
        what = f"{args.algorithm} ({echo.n_rx} receivers merged by PCA)" if echo.n_rx > 1 else args.algorithm
    if args.window:
        what += f", {args.window} window"
    took = time.perf_counter() - t
    print(f"{what}: image {' x '.join(map(str, image.shape))} ({', '.join(image.dims)}) in {took:.1f} s")
    if args.out:
        print(f"-> {io.save(image, outputs['-o'])}")
    if args.png:
        write_png(image, outputs["--png"], args.floor, f"{Path(args.echo).name}: {args.algorithm}")
        print(f"-> {args.png}")
    return 0


def add_plot_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="an image or echo file (.nc or .zarr)")
    parser.add_argument("-o", "--out", "--png", dest="out", default=None,
                        help="picture to write: .png, .pdf or .svg (default: FILE with .png)")
    parser.add_argument("--floor", type=float, default=-50.0, help="floor, dB (default -50)")
    parser.add_argument("--rx", default="0", help="echo files: the receiver shown (index or name)")
    add_overwrite_argument(parser)


def run_plot(args) -> int:
    from .. import io
    from ..model import EchoData, Image

    picture = args.out or str(Path(args.file).with_suffix(".png"))
    out = check_outputs({}, {"-o": picture}, inputs=(args.file,), overwrite=args.overwrite)["-o"]
    _check_floor(args.floor)
    obj = io.load(args.file)
    if isinstance(obj, EchoData):
        rx = obj.select_receivers([int(args.rx) if args.rx.isdigit() else args.rx], "--rx")[0]
        shown = Image(data=obj.data[rx], dims=("eta", "tau"), axes={"eta": obj.eta, "tau": obj.fast_time(rx)})
        title = f"{Path(args.file).name}: receiver {obj.receivers[rx]}"
    else:
        if obj.data.ndim != 2:
            raise UsageError(f"{args.file}: a {obj.data.ndim}-D image; pictures are of 2-D images")
        shown, title = obj, f"{Path(args.file).name}: {obj.provenance.get('algorithm', '')}"
    write_png(shown, out, args.floor, title)
    print(f"-> {out}")
    return 0


def _check_floor(floor: float) -> None:
    if not (np.isfinite(floor) and -1000 <= floor < 0):
        raise UsageError(f"--floor: must be a number of dB in [-1000, 0), got {floor:g}")


def _size(path: Path) -> int:
    path = Path(path)
    if path.is_dir():
        return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    return path.stat().st_size
