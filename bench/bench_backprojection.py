"""Back-projection throughput: giga back-projections per second (pixels x pulses x receivers / s).

The issue's configuration: 512 x 512 pixels x 1024 pulses x records of 4096 range-compressed
samples, one receiver. Scene: a monostatic straight track (1 m/s, 20 Hz PRF, 150 kHz carrier,
B = 20 kHz sampled at fs = 40 kHz, so 4096 samples span 102 ms, i.e. 35 m to 112 m of range),
the plane 40-100 m across track by +-15 m along track (0.12 m x 0.06 m pixels); the data are
random (the rate does not depend on their content).

Cases, the ``clsas.backproject`` call timed whole (grid tiling, per-tile references, record
uploads and the kernel; builds and warm-up excluded):

- ``sinc8``: the 8-tap windowed sinc on the original 4096 samples.
- ``linear``: linear interpolation with ``upsample=1`` on the same 4096-sample records read
  as data that is already upsampled (in use the FFT upsampling happens once per echo, in
  ``range_compress(..., upsample=8)``, not in every back-projection); the kernel's work per
  pixel and pulse does not depend on the band the samples carry.
- ``linear-x8`` (not with ``--quick``): the records a real x8 upsampling of that scene gives,
  32768 samples covering the same range window, to show what the longer records cost (cache).

Against torchbp (``bench: "backprojection-vs-torchbp"``, when ``torchbp`` is importable; the
rows say so when it is not): the issue's scene (512^2 px x 1024 pulses x 4096 samples, linear,
monostatic) imaged by ``clsas.backproject`` (upsample=1) and by torchbp's Cartesian CPU
back-projection (``torchbp.ops.backprojection_cart_2d``: a float32 distance and one square root a
pixel and pulse, stop-and-go, linear interpolation; its speed of light stands in for the sound
speed through its carrier argument), timed interleaved (clsas, torchbp, clsas, ...), min and
median, for clsas with ``stop_and_go=True`` (the same delays) and with its default exact
non-stop-and-go delays; the relative L2 difference of the stop-and-go images is reported.
torchbp is built from source against torch (CPU) in its own environment, which must also hold
clsas to run this bench; the rows' ``torchbp`` note names the ``-march`` its extension was compiled
with (from the compiler's command line its debug information keeps), so that a row says which build
it timed. The clsas rows also carry (medians over the timed calls) ``kernel_seconds``, bp_tile's own
time in a call (its profiling events, the image's provenance), ``outside_kernels_seconds``, the
call's wall time less that (the host's work before the first and after the last launch, bp_fields,
bp_refs and the gaps between commands: what separates the wall-time ratio from the CPU-time ratio),
and ``host_cpu_seconds``, the calling thread's CPU time over the call (the host's own work; where
``outside_kernels_seconds`` is much larger the host thread was waiting, e.g. descheduled by the
device's threads or other processes).

NumPy (the float64 reference) runs on fewer pulses (its rate does not depend on the pulse
count). Each figure is the median of several timed runs; the fastest run is reported as
``min_seconds`` / ``rate_best`` beside it (the machine is shared: spread is noise).

Fixed cost (issue 19; ``bench: "backprojection-fixed-cost"``): Huang & Yang 2022's sonar
(``presets.point_scene("huang2022", n_pulses=64)``: 32 receivers x 64 pulses, range-compressed,
default options: linear, upsample 8) imaged on grids of 128^2, 256^2 (and 512^2 without
``--quick``) pixels, each over two extents: ``scene`` (x 35-85 m, y +-6 m: the six targets, the
whole record's range) and ``patch`` (6 m x 6 m around the target at 60 m). Four ways, timed
interleaved (A B C D, A B C D, ...), warm (one untimed round first):

- ``plain``: ``backproject(echo, grid)``, a first call on the echo (it upsamples the span the
  grid reaches; the grid's tile plan is made by its first call, the untimed warm-up, and kept
  while the Grid object lives, as a GridPlan would be);
- ``prepared``: ``backproject(records, plan)`` on records from ``prepare(echo)`` (every sample,
  made once) and a ``GridPlan`` of the grid: a further call on prepared records;
- ``whole-records``: ``backproject(prepare(echo), grid)``: every record upsampled in every call,
  as the path before prepared records did (with the same block upsampling, so the difference is
  the span alone);
- ``kernel_seconds`` beside each: the kernels' own time in that call (profiling events), and
  ``over_kernel`` = whole call / kernel time (issue 19 asks <= 2 for prepared, <= 3 for plain
  at 128^2 on the scene).

The grid sizes of one extent are timed interleaved too (every size and way once a round), and each
row carries ``over_largest``: its median over the median of the same way on the largest grid of
its extent (issue 31 item 3 asks <= 0.15 for a plain 128^2 call against a plain 512^2 call), and
``over_largest_min`` from the fastest runs.

The torchbp and fixed-cost rows also carry ``cpu_seconds`` (median) and ``cpu_min_seconds``: the CPU time of the
whole process over the call (every thread: PoCL's workers, torch's OpenMP threads, the host), and
the torchbp rows ``ratio_cpu_median`` (torchbp's CPU seconds over clsas's): on a shared machine a
process's CPU time counts the work it did, where its wall time also counts the time other
processes held the cores, so that ratio moves less with the load than the wall-time ratio (both are
reported; the wall-time ratio on a quiet machine is the issue's figure).

Rows a work-item (``bench: "backprojection-rows"``): the issue's scene (stop-and-go, linear,
upsample 1) on ``GridPlan(grid, rows=r)`` for r = 4, 6 (the default) and 8, interleaved, with
``over_rows4`` (median wall and CPU time over those of 4 rows): bp_tile's work-item holds r rows of
16 pixels.

The compiled loop (``bench: "backprojection-loop"``, only with ``--only loop``, which sets
PoCL's kernel cache to a fresh directory before the device starts): bp_tile for the issue's scene
(linear, upsample 1; stop-and-go and exact delays) built by PoCL, its pulse loop on the leg
polynomial's arm (the shortest cycle of the work-group function's basic blocks without a square root
through its largest such block; with exact delays, the path that holds w . delta) disassembled by
``objdump`` and analysed by ``llvm-mca`` for the CPU model given by ``--mcpu``
(default icelake-server): instructions and uops an iteration, llvm-mca's cycles an iteration and
per pixel-pulse (an iteration is ROWS rows of 16 pixels and one pulse), the pressure on ports 0
and 5 (the two 512-bit vector ports) and on the load ports, beside the measured single-thread CPU
time per pixel-pulse of the whole call (POCL_MAX_PTHREAD_COUNT=1 is not set here: the process's
CPU time over all threads, divided by pixel-pulses). Wall times move with the load; these counts
do not, but neither are they the loop's bound on the machine docs/design.md describes (its
data-dependent sample reads are: removing a fifth of the vector uops left the time unchanged).

``--only torchbp|fixed-cost|rates|rows|loop`` runs one part.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
from _harness import arguments, report

import clsas
from clsas import EchoData, Medium, Waveform
from clsas.model import Grid
from clsas.image.backprojection import GridPlan, backproject, prepare
from clsas.scene import presets

FS = 40e3


def scene(n_pulses: int, n_samples: int, n_pixels: int, fs: float = FS):
    wf = Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=FS)
    eta = (np.arange(n_pulses) - n_pulses / 2) / 20.0
    tx = np.column_stack([np.zeros(n_pulses), 1.0 * eta, np.zeros(n_pulses)])
    rx_tau = np.array([0.0, 0.2])
    rx = np.stack([tx, tx + [0.0, 0.2, 0.0]], axis=1)[None]  # the receiver moves on at 1 m/s
    rng = np.random.default_rng(0)
    data = (rng.standard_normal((1, n_pulses, n_samples), dtype=np.float32)
            + 1j * rng.standard_normal((1, n_pulses, n_samples), dtype=np.float32))
    echo = EchoData(data=data, eta=eta, t0=[2 * 35.0 / 1500.0], fs=fs, tx_pos=tx, rx_pos=rx, rx_tau=[rx_tau],
                    waveform=wf, medium=Medium(1500.0), receivers=("A",), compressed=True)
    grid = Grid.plane(np.linspace(40.0, 100.0, n_pixels), np.linspace(-15.0, 15.0, n_pixels), 0.0)
    return echo, grid


def timings(run, repeats: int) -> list[float]:
    """Wall times of ``repeats`` runs after one warm-up run (kernel builds, caches)."""
    run()
    return [timed(run)[1] for _ in range(repeats)]


def timed(run):
    """``run()``'s result, its wall time and the process's CPU time over it (s)."""
    wall, cpu = time.perf_counter(), time.process_time()
    out = run()
    return out, time.perf_counter() - wall, time.process_time() - cpu


TORCHBP_C0 = 299792458.0  # torchbp's speed of light (csrc/cpu/util.h kC0)


def torchbp_call(echo, grid):
    """A function imaging ``echo`` (one receiver, stop-and-go, monostatic) on the plane ``grid``
    with torchbp's Cartesian CPU back-projection, returning the image as (y, x) complex64; or the
    reason it cannot."""
    try:
        import torch
        import torchbp
    except ImportError as exc:
        return None, f"torchbp is not importable here ({exc}); build it from source in an environment with torch"
    c, f0 = echo.medium.sound_speed, echo.waveform.f0
    x, y = grid.axes["x"], grid.axes["y"]
    data = torch.from_numpy(np.ascontiguousarray(echo.data[0]))
    pos = torch.from_numpy(np.ascontiguousarray(echo.tx_pos - [0.0, 0.0, grid.positions[0, 0, 2]], np.float32))
    spec = {"x": (x[0], x[0] + x.size * (x[1] - x[0])), "y": (y[0], y[0] + y.size * (y[1] - y[0])), "nx": x.size,
            "ny": y.size}
    # sample k of the record is at range c (t0 + k / fs) / 2: bins of c / (2 fs), starting at c t0 / 2; the
    # carrier phase 4 pi fc d / C0 is clsas's 4 pi f0 d / c when fc = f0 C0 / c
    args = dict(fc=f0 * TORCHBP_C0 / c, r_res=c / (2 * echo.fs), pos=pos, d0=-c * echo.t0[0] / 2)

    def run():
        return torchbp.ops.backprojection_cart_2d(data, spec, **args).numpy()[0].T

    return run, f"torch {torch.__version__}, {torch.get_num_threads()} threads, torchbp {torchbp_build(torchbp)}"


def torchbp_build(torchbp) -> str:
    """The ``-march`` torchbp's compiled extension was built with, as the compiler's command line
    in its debug information records it, or that it is not recorded."""
    import glob
    import os
    import re

    for path in sorted(glob.glob(os.path.join(os.path.dirname(torchbp.__file__), "_C*.so"))):
        with open(path, "rb") as f:
            found = re.search(rb"-march=[\w.-]+", f.read())
        if found:
            return found.group(0).decode()
    return "(-march not recorded)"


def versus_torchbp(args) -> None:
    """The torchbp rows (module docstring)."""
    n_pix, n_pulses = (256, 256) if args.quick else (512, 1024)
    echo, grid = scene(n_pulses, 4096, n_pix)
    run_torchbp, note = torchbp_call(echo, grid)
    size = {"pixels": grid.size, "pulses": n_pulses, "receivers": 1, "samples": 4096}
    if run_torchbp is None:
        report(args, "backprojection-vs-torchbp", "opencl", size, float("nan"), "G backprojections/s", float("nan"),
               case="not run", note=note)
        return
    repeats = args.repeats or (3 if args.quick else 5)
    work = grid.size * n_pulses / 1e9
    theirs = run_torchbp()
    for case, stop_and_go in (("stop-and-go", True), ("default", False)):
        def ours():
            return backproject(echo, grid, backend="opencl", interp="linear", upsample=1, stop_and_go=stop_and_go,
                               progress=False)
        image = ours()
        run_torchbp()
        times = {"clsas": [], "torchbp": []}
        cpu = {"clsas": [], "torchbp": []}
        kernels, outside, host = [], [], []  # clsas: bp_tile's time, the wall time outside it, the host thread's CPU
        for _ in range(repeats):
            for name, run in (("clsas", ours), ("torchbp", run_torchbp)):
                thread = time.thread_time()
                out, wall, used = timed(run)
                thread = time.thread_time() - thread
                times[name].append(wall)
                cpu[name].append(used)
                if name == "clsas":
                    kernels.append(out.provenance["kernel_seconds"])
                    outside.append(wall - kernels[-1])
                    host.append(thread)
        med = {k: statistics.median(v) for k, v in times.items()}
        cpu_med = {k: statistics.median(v) for k, v in cpu.items()}
        agree = float(np.linalg.norm(image.data - theirs) / np.linalg.norm(image.data)) if stop_and_go else None
        for name in ("clsas", "torchbp"):
            report(args, "backprojection-vs-torchbp", "opencl" if name == "clsas" else "torchbp-cpu", size,
                   work / med[name], "G backprojections/s", med[name], case=case, method=name,
                   min_seconds=min(times[name]), rate_best=work / min(times[name]), runs=repeats,
                   cpu_seconds=cpu_med[name], cpu_min_seconds=min(cpu[name]),
                   **({"ratio_median": med["torchbp"] / med["clsas"],
                       "ratio_best": min(times["torchbp"]) / min(times["clsas"]),
                       "ratio_cpu_median": cpu_med["torchbp"] / cpu_med["clsas"], "torchbp": note,
                       "rel_l2_vs_torchbp": agree, "kernel_seconds": statistics.median(kernels),
                       "outside_kernels_seconds": statistics.median(outside),
                       "host_cpu_seconds": statistics.median(host)} if name == "clsas" else {}))


def fixed_cost(args) -> None:
    """The fixed-cost rows (module docstring)."""
    echo = clsas.range_compress(clsas.simulate(presets.point_scene("huang2022", n_pulses=64), backend="opencl",
                                               progress=False))
    records = prepare(echo)
    extents = {"scene": ((35.0, 85.0), (-6.0, 6.0)), "patch": ((57.0, 63.0), (-3.0, 3.0))}
    sizes = (128, 256) if args.quick else (128, 256, 512)
    repeats = args.repeats or (3 if args.quick else 5)
    for extent, (xs, ys) in extents.items():
        grids = {n: Grid.plane(np.linspace(*xs, n), np.linspace(*ys, n), 0.0) for n in sizes}
        runs = {}
        for n, grid in grids.items():
            plan = GridPlan(grid)
            runs.update({(n, "plain"): lambda grid=grid: backproject(echo, grid, progress=False),
                         (n, "prepared"): lambda plan=plan: backproject(records, plan, progress=False),
                         (n, "whole-records"): lambda grid=grid: backproject(prepare(echo), grid, progress=False)})
        for run in runs.values():
            run()  # warm-up: kernel builds, first touch
        seconds, cpu, kernel = ({key: [] for key in runs} for _ in range(3))
        for _ in range(repeats):  # every size and way once a round
            for key, run in runs.items():
                image, wall, used = timed(run)
                seconds[key].append(wall)
                cpu[key].append(used)
                kernel[key].append(image.provenance["kernel_seconds"])
        largest = max(sizes)
        for (n, way) in runs:
            grid = grids[n]
            work = grid.size * echo.n_pulses * echo.n_rx / 1e9
            median, k_median = statistics.median(seconds[n, way]), statistics.median(kernel[n, way])
            report(args, "backprojection-fixed-cost", "opencl",
                   {"pixels": grid.size, "pulses": echo.n_pulses, "receivers": echo.n_rx,
                    "samples": echo.n_samples}, work / median, "G backprojections/s", median, case=way,
                   grid=f"{extent} {n}^2", min_seconds=min(seconds[n, way]), kernel_seconds=k_median,
                   kernel_min_seconds=min(kernel[n, way]), over_kernel=median / k_median,
                   over_largest=median / statistics.median(seconds[largest, way]),
                   over_largest_min=min(seconds[n, way]) / min(seconds[largest, way]),
                   cpu_seconds=statistics.median(cpu[n, way]), cpu_min_seconds=min(cpu[n, way]), runs=repeats,
                   **({"prepared_records_mb": records.nbytes / 2**20} if way == "prepared" else {}))


def rates(args) -> None:
    """The ``backprojection`` rows (module docstring): OpenCL and NumPy on the bench scene."""
    n_pix = 256 if args.quick else 512
    pulses = {"opencl": 256 if args.quick else 1024, "numpy": 8 if args.quick else 16}
    cases = [("sinc8", "sinc8", 4096, FS), ("linear", "linear", 4096, FS)]
    if not args.quick:
        cases.append(("linear-x8", "linear", 8 * 4096, 8 * FS))
    for case, interp, n_samples, fs in cases:
        rate = {}
        for backend, n_pulses in pulses.items():
            echo, grid = scene(n_pulses, n_samples, n_pix, fs)
            times = timings(lambda: backproject(echo, grid, backend=backend, interp=interp, upsample=1,
                                                progress=False),
                            args.repeats or (5 if backend == "opencl" else 1))
            work = grid.size * n_pulses / 1e9
            seconds = statistics.median(times)
            rate[backend] = work / seconds
            report(args, "backprojection", backend, {"pixels": grid.size, "pulses": n_pulses, "receivers": 1,
                                                     "samples": n_samples},
                   rate[backend], "G backprojections/s", seconds, interp=interp, case=case,
                   min_seconds=min(times), rate_best=work / min(times), runs=len(times),
                   **({"speedup": rate["opencl"] / rate["numpy"]} if backend == "numpy" else {}))


def rows(args) -> None:
    """The ``backprojection-rows`` rows (module docstring)."""
    n_pix, n_pulses = (256, 256) if args.quick else (512, 1024)
    echo, grid = scene(n_pulses, 4096, n_pix)
    plans = {r: GridPlan(grid, rows=r) for r in (4, 6, 8)}
    runs = {r: (lambda plan=plan: backproject(echo, plan, interp="linear", upsample=1, stop_and_go=True,
                                              progress=False)) for r, plan in plans.items()}
    for run in runs.values():
        run()  # warm-up: kernel builds, tilings
    seconds, cpu = {r: [] for r in runs}, {r: [] for r in runs}
    for _ in range(args.repeats or (3 if args.quick else 5)):
        for r, run in runs.items():
            _, wall, used = timed(run)
            seconds[r].append(wall)
            cpu[r].append(used)
    work = grid.size * n_pulses / 1e9
    for r in runs:
        median = statistics.median(seconds[r])
        report(args, "backprojection-rows", "opencl", {"pixels": grid.size, "pulses": n_pulses, "receivers": 1,
                                                       "samples": 4096}, work / median, "G backprojections/s",
               median, rows=r, min_seconds=min(seconds[r]), cpu_seconds=statistics.median(cpu[r]),
               cpu_min_seconds=min(cpu[r]), over_rows4=median / statistics.median(seconds[4]),
               over_rows4_cpu=statistics.median(cpu[r]) / statistics.median(cpu[4]), runs=len(seconds[r]))


def _pulse_loop(asm: str) -> list[str]:
    """The instructions (AT&T, no branches) of bp_tile's pulse loop on the leg polynomial's arm in
    its work-group function of ``objdump -d`` output ``asm``: the function's basic blocks, the
    largest block that lies on a cycle of blocks without a square root or division (the stable
    root's arm has them), and the shortest such cycle through it (by instructions), in the order
    its blocks run. With exact delays (MONO) that is the path that holds w . delta (a receiver at constant
    velocity), not the one that remakes it."""
    import heapq
    import re

    func, found = None, []
    for line in asm.splitlines():
        head = re.match(r"^[0-9a-f]+ <(.*)>:", line)
        if head:
            func = head.group(1)
            continue
        m = re.match(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
        if m and func and func.endswith("bp_tile_workgroup_fast"):
            target = re.match(r"([0-9a-f]+) <", m.group(3))
            found.append((int(m.group(1), 16), m.group(2), re.sub(r"\s*#.*$", "", m.group(3)),
                          int(target.group(1), 16) if target and m.group(2).startswith("j") else None))
    if not found:
        return []
    # basic blocks: a block starts at a jump's target and after a jump
    starts = {found[0][0]} | {t for *_, t in found if t is not None}
    starts |= {found[k + 1][0] for k, (_, op, _, _) in enumerate(found[:-1]) if op.startswith("j")}
    blocks, index = [], {}
    for a, op, arg, target in found:
        if a in starts or not blocks:
            index[a] = len(blocks)
            blocks.append([])
        blocks[-1].append((op, arg, target))
    succ = []  # each block's successors: its jump's target, and the next block unless it ends in jmp or ret
    for k, block in enumerate(blocks):
        op, _, target = block[-1]
        succ.append(([index[target]] if target in index else [])
                    + ([k + 1] if k + 1 < len(blocks) and op != "jmp" and not op.startswith("ret") else []))
    free = [not any(op.startswith(("vsqrt", "vdiv", "sqrt", "div")) for op, _, _ in b) for b in blocks]
    size = [sum(not op.startswith("j") for op, _, _ in b) for b in blocks]

    def shortest_cycle(k: int):
        """The sqrt-free cycle through block k with the fewest instructions (Dijkstra back to k)."""
        heap, best, back = [(size[k], k)], {k: size[k]}, {}
        while heap:
            d, u = heapq.heappop(heap)
            if d > best.get(u, float("inf")):
                continue
            for v in succ[u]:
                if not free[v]:
                    continue
                if v == k:
                    path = [u]
                    while path[-1] != k:
                        path.append(back[path[-1]])
                    return path[::-1]  # in the order they run, from block k
                if d + size[v] < best.get(v, float("inf")):
                    best[v], back[v] = d + size[v], u
                    heapq.heappush(heap, (d + size[v], v))
        return None

    for k in sorted((k for k in range(len(blocks)) if free[k]), key=lambda k: -size[k]):
        cycle = shortest_cycle(k)
        if cycle:
            return [f"{op} {re.sub(r'<[^>]*>', '', arg)}" for b in cycle for op, arg, _ in blocks[b]
                    if not op.startswith("j")]
    return []


def loop(args) -> None:
    """The ``backprojection-loop`` rows (module docstring)."""
    import glob
    import os
    import re
    import shutil
    import subprocess

    tools = shutil.which("llvm-mca-15") or shutil.which("llvm-mca"), shutil.which("objdump")
    size = {"pixels": 256 * 256, "pulses": 256, "receivers": 1, "samples": 4096}
    if None in tools or _LOOP_CACHE is None or os.environ.get("POCL_CACHE_DIR") != _LOOP_CACHE:
        report(args, "backprojection-loop", "opencl", size, float("nan"), "cycles/pixel-pulse", float("nan"),
               case="not run", note="needs llvm-mca and objdump, and --only loop (a fresh PoCL cache)")
        return
    echo, grid = scene(256, 4096, 256)
    plan = GridPlan(grid)
    for case, stop_and_go in (("stop-and-go", True), ("default", False)):
        before = set(glob.glob(os.path.join(os.environ["POCL_CACHE_DIR"], "**", "bp_tile.so"), recursive=True))

        def run():
            return backproject(echo, plan, interp="linear", upsample=1, stop_and_go=stop_and_go, progress=False)
        run()
        built = sorted(set(glob.glob(os.path.join(os.environ["POCL_CACHE_DIR"], "**", "bp_tile.so"), recursive=True))
                       - before, key=os.path.getmtime)
        asm = subprocess.run([tools[1], "-d", "--no-show-raw-insn", built[-1]], capture_output=True, text=True).stdout
        body = _pulse_loop(asm)
        if not body:
            report(args, "backprojection-loop", "opencl", size, float("nan"), "cycles/pixel-pulse", float("nan"),
                   case=case, note="no pulse loop without a square root found in the compiled bp_tile")
            continue
        out = subprocess.run([tools[0], f"-mcpu={args.mcpu}", "-iterations=200"], input="\n".join(body) + "\n",
                             capture_output=True, text=True).stdout
        cycles = float(re.search(r"Total Cycles:\s+(\d+)", out).group(1)) / 200
        uops = float(re.search(r"Total uOps:\s+(\d+)", out).group(1)) / 200
        lines = out.splitlines()
        at = next(k for k, line in enumerate(lines) if line.startswith("Resource pressure per iteration"))
        names = dict(re.findall(r"\[(\d+)\]\s+-\s+\w+?(Port\d+)", out))
        pressure = dict(zip(re.findall(r"\[(\d+)\]", lines[at + 1]), lines[at + 2].split()))
        port = {names[k]: float(v) for k, v in pressure.items() if k in names and v != "-"}
        per_iteration = plan.tiling(echo.waveform.f0, echo.medium.sound_speed).rows * 16
        cpu = [timed(run)[2] for _ in range(args.repeats or 3)]
        work = grid.size * echo.n_pulses
        report(args, "backprojection-loop", "opencl", size, cycles / per_iteration, "cycles/pixel-pulse",
               statistics.median(cpu), case=case, mcpu=args.mcpu, instructions=len(body), uops=uops,
               cycles_per_iteration=cycles, pixel_pulses_per_iteration=per_iteration,
               vector_uops_per_pixel_pulse=(port.get("Port0", 0.0) + port.get("Port5", 0.0)) / per_iteration,
               port0=port.get("Port0"), port5=port.get("Port5"), loads=port.get("Port2", 0.0) + port.get("Port3", 0.0),
               cpu_ns_per_pixel_pulse=1e9 * min(cpu) / work)


PARTS = {"torchbp": versus_torchbp, "fixed-cost": fixed_cost, "rates": rates, "rows": rows, "loop": loop}
_LOOP_CACHE = None  # the fresh PoCL kernel cache of ``--only loop``


def main() -> None:
    global _LOOP_CACHE
    import os
    import tempfile

    args = arguments(__doc__.splitlines()[0], parts=PARTS,
                     extra=[("--mcpu", dict(default="icelake-server", help="llvm-mca's CPU model (--only loop)"))])
    if args.only == "loop":  # before the device starts (nothing has touched OpenCL yet): a fresh kernel cache
        _LOOP_CACHE = os.environ["POCL_CACHE_DIR"] = tempfile.mkdtemp(prefix="clsas-bp-loop-")
    try:
        for name, part in PARTS.items():
            if args.only == name or (args.only is None and name != "loop"):
                part(args)
    finally:
        if _LOOP_CACHE is not None:
            import shutil

            shutil.rmtree(_LOOP_CACHE, ignore_errors=True)


if __name__ == "__main__":
    main()
