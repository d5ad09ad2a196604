"""The ``clsas`` command (also ``python -m clsas``).

Sub-commands: simulate, image, plot (the file workflow, :mod:`clsas.cli.workflow`), info,
demo, bench, and ``reproduce PAPER`` (one sub-command per module of :mod:`clsas.reproduce`).
A mistake in the arguments or the files prints one line ``clsas: error: ...`` and exits with
status 2; Ctrl-C prints ``clsas: interrupted`` and exits with status 130 (an output being
written is not left behind: :mod:`clsas.atomic`); ``CLSAS_DEBUG=1`` shows the traceback instead.
"""

from __future__ import annotations

import argparse
import functools
import logging
import os
import sys

from ._common import UsageError, add_overwrite_argument, check_json

DESCRIPTION = """\
Synthetic aperture sonar simulation and imaging.

examples:
  clsas simulate huang2022 -o echo.nc --pulses 128 --snr 20 --seed 1
  clsas image echo.nc --algorithm omegak -o image.nc --png image.png
  clsas image echo.nc --algorithm bp --grid 38:42:0.01,-2:2:0.01,-10 --png bp.png
  clsas plot image.nc
  clsas info
  clsas reproduce --help

files are NetCDF4 (.nc) or zarr (.zarr); xarray.open_dataset reads them. An existing output
is replaced only with --overwrite, the input never; an interrupted command leaves no output.
environment: CLSAS_BACKEND (auto, opencl, numpy), CLSAS_DEVICE (an OpenCL device),
TQDM_DISABLE=1 (no progress bars), CLSAS_DEBUG=1 (tracebacks, compiler output).
"""


def _version() -> str:
    from .. import __version__

    return f"clsas {__version__}"


def build_parser(argv=None) -> argparse.ArgumentParser:
    from . import bench, demo, info, workflow

    parser = argparse.ArgumentParser(prog="clsas", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=_version())
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="log the stages (device, sizes, times); -vv adds debug detail")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bars")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands = [
        ("simulate", "simulate a preset's echoes into a file", workflow.add_simulate_arguments, workflow.run_simulate),
        ("image", "form an image from an echo file", workflow.add_image_arguments, workflow.run_image),
        ("plot", "picture of an image or echo file (PNG)", workflow.add_plot_arguments, workflow.run_plot),
        ("info", "clsas version, backend, OpenCL device and its driver's source", info.add_arguments, info.run),
        ("demo", "end-to-end check on this machine (about 10 s)", demo.add_arguments, demo.run),
        ("bench", "time the workflow's stages on this machine", bench.add_arguments, bench.run),
    ]
    for name, help_text, add_arguments, run in commands:
        one = sub.add_parser(name, help=help_text, description=help_text)
        add_arguments(one)
        one.set_defaults(run=run)
    _add_reproductions(sub, sys.argv[1:] if argv is None else list(argv))
    return parser


def _add_reproductions(sub, argv: list) -> None:
    """``clsas reproduce PAPER [options]``: one sub-command per module of :mod:`clsas.reproduce`.
    Only the paper named on the command line is imported (the others' help lines are read from
    their sources), so that every other command starts without importing them all."""
    from .. import reproduce

    chosen = None
    if "reproduce" in argv:
        rest = [a for a in argv[argv.index("reproduce") + 1:] if not a.startswith("-")]
        chosen = rest[0] if rest else None
    parser = sub.add_parser("reproduce", help="reproduce a source paper's tables")
    which = parser.add_subparsers(dest="paper", required=True, metavar="PAPER")
    for name in reproduce.paper_names():
        one = which.add_parser(name, help=reproduce.summary(name))
        if name == chosen:
            module = reproduce.paper(name)
            module.add_arguments(one)
            add_overwrite_argument(one)
            one.set_defaults(run=functools.partial(_reproduce, module.run))


def _reproduce(run, args) -> int:
    """A reproduction, its ``--json`` output checked first as every command's outputs are."""
    if getattr(args, "json", None) is not None:
        check_json("--json", args.json, args.overwrite)
    return run(args)


def _configure_logging(verbose: int) -> None:
    if verbose:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(asctime)s clsas %(levelname)s %(message)s", "%H:%M:%S"))
        logger = logging.getLogger("clsas")
        logger.addHandler(handler)
        logger.setLevel(logging.INFO if verbose == 1 else logging.DEBUG)


def main(argv=None) -> int:
    try:
        return _main(argv)
    except KeyboardInterrupt:  # Ctrl-C while the arguments are read (the commands' own is below)
        if os.environ.get("CLSAS_DEBUG", "") not in ("", "0"):
            raise
        print("clsas: interrupted", file=sys.stderr)
        return 130


def _main(argv) -> int:
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    _configure_logging(args.verbose)
    if not args.progress:
        os.environ["TQDM_DISABLE"] = "1"
    debug = os.environ.get("CLSAS_DEBUG", "") not in ("", "0")
    try:
        return args.run(args)
    except KeyboardInterrupt:
        if debug:
            raise
        print("clsas: interrupted", file=sys.stderr)
        return 130
    except (UsageError, ValueError, TypeError, OSError, RuntimeError, MemoryError) as err:
        if debug:
            raise
        message = " ".join(str(err).split()) or type(err).__name__
        if isinstance(err, MemoryError):
            message = f"out of memory ({message}); lower the sizes or CLSAS_MEMORY_BUDGET"
        print(f"clsas: error: {message}", file=sys.stderr)
        return 2
    except SystemExit as stop:  # a command's own refusal, SystemExit("message") (the reproductions'):
        if not isinstance(stop.code, str):  # one error line and status 2, as every other command's
            raise
        print(f"clsas: error: {' '.join(stop.code.split())}", file=sys.stderr)
        return 2
