"""EchoData and Image as xarray Datasets (CF conventions), and back.

Ground floor: imports the containers and the scenario types they record; xarray is imported
when a conversion runs.

An EchoData becomes (``ds.attrs["clsas_kind"] == "EchoData"``)::

    echo    complex64 (rx, pulse, sample)   baseband samples ("1": relative amplitude)
    rx      str (rx)          receiver names                  coordinate
    pulse   int64 (pulse)     pulse index                     coordinate
    sample  int64 (sample)    fast-time sample index          coordinate
    eta     float64 (pulse)   emission time (slow time), s    coordinate
    t0      float64 (rx)      fast time of sample 0, s        coordinate
    tau     float64 (rx, sample)  fast time t0 + sample / fs, s   2-D coordinate (derived)
    xyz     str (xyz)         "x", "y", "z"                   coordinate
    tx_pos  float64 (pulse, xyz)          transmitter phase centre, m
    rx_pos  float64 (rx, pulse, node, xyz) receiver phase centres at the nodes, m
    rx_tau  float64 (rx, node)            fast times of the nodes, s
    attrs: Conventions, title, clsas_kind, clsas_format, clsas_version, fs (Hz), compressed
           (0/1), waveform, medium, provenance (JSON text), and scenario: the whole Scenario
           the echoes were simulated from as TOML text (docs/scenario-toml.md; meshes inline),
           when there is one (``clsas.load(path).scenario`` rebuilds it;
           ``clsas.scene.toml.scenario_from_toml(ds.attrs["scenario"])`` too). A scenario TOML
           cannot hold (motion errors as Python functions) is left out with a warning, and
           ``scenario_missing`` says why.

An Image becomes ``image`` complex64 over its own dims, one coordinate per dim (units from
:data:`AXIS_UNITS`: m for x, y, z, u, v, r; s for eta, tau), and the pixel positions either
as the scalar coordinate ``z`` (a horizontal plane: positions follow from the x and y axes,
checked bit for bit before they are dropped) or as ``positions (dims..., xyz)`` in m.
"""

from __future__ import annotations

import dataclasses
import json
import logging

import numpy as np

from ..version import __version__
from ..model import AXIS_UNITS, EchoData, Image, Medium, Waveform
from .toml import scenario_from_toml, scenario_to_toml

log = logging.getLogger("clsas")

FORMAT = 2  # clsas_format of these datasets; 1 was the h5py layout of clsas 0.1 (io reads it)

_ECHO_NAMES = ("echo", "rx", "pulse", "sample", "eta", "t0", "tau", "xyz", "node", "tx_pos", "rx_pos", "rx_tau")


def _xarray():
    try:
        import xarray as xr
    except ImportError as err:  # pragma: no cover - xarray is a core dependency
        raise ImportError("clsas files need xarray: pip install xarray h5netcdf") from err
    return xr


def to_json(value) -> str:
    """JSON text of ``value`` (arrays as lists, dataclasses as dicts); TypeError naming what cannot be stored."""
    def default(obj):
        if isinstance(obj, np.ndarray):
            return obj.tolist()
        if isinstance(obj, np.generic):
            return obj.item()
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            return dataclasses.asdict(obj)
        raise TypeError(f"cannot store a {type(obj).__name__} in a clsas file (provenance values must be "
                        "numbers, strings, lists, dicts or arrays)")

    return json.dumps(value, default=default)


def _version() -> str:
    return __version__


def _attrs(kind: str, title: str, provenance: dict) -> dict:
    return {"Conventions": "CF-1.8", "title": title, "clsas_kind": kind, "clsas_format": FORMAT,
            "clsas_version": _version(), "provenance": to_json(provenance)}


def echo_to_xarray(echo: EchoData):
    """The xarray.Dataset of ``echo`` (layout in the module docstring); arrays are not copied."""
    xr = _xarray()
    tau = echo.t0[:, None] + np.arange(echo.n_samples)[None, :] / echo.fs
    what = "range-compressed" if echo.compressed else "raw"
    coords = {
        "rx": ("rx", np.array(echo.receivers, dtype=str), {"long_name": "receiver name"}),
        "pulse": ("pulse", np.arange(echo.n_pulses), {"long_name": "pulse index", "units": "1"}),
        "sample": ("sample", np.arange(echo.n_samples), {"long_name": "fast-time sample index", "units": "1"}),
        "eta": ("pulse", echo.eta, {"long_name": "emission time of the pulse (slow time)", "units": "s"}),
        "t0": ("rx", echo.t0, {"long_name": "fast time of sample 0 after the emission", "units": "s"}),
        "tau": (("rx", "sample"), tau, {"long_name": "fast time after the emission (t0 + sample / fs)", "units": "s"}),
        "xyz": ("xyz", np.array(["x", "y", "z"]), {"long_name": "world axis (x across track, y along track, z up)"}),
        "node": ("node", np.arange(echo.rx_tau.shape[1]), {"long_name": "receiver track node index", "units": "1"}),
    }
    data_vars = {
        "echo": (("rx", "pulse", "sample"), echo.data,
                 {"long_name": f"{what} complex baseband echo samples", "units": "1"}),
        "tx_pos": (("pulse", "xyz"), echo.tx_pos, {"long_name": "transmitter phase centre at emission", "units": "m"}),
        "rx_pos": (("rx", "pulse", "node", "xyz"), echo.rx_pos,
                   {"long_name": "receiver phase centre at time eta + rx_tau (linear between nodes)", "units": "m"}),
        "rx_tau": (("rx", "node"), echo.rx_tau, {"long_name": "fast time of each receiver track node", "units": "s"}),
    }
    attrs = _attrs("EchoData", f"clsas EchoData: {what} echoes, {echo.n_rx} receivers x {echo.n_pulses} pulses "
                   f"x {echo.n_samples} samples", echo.provenance)
    attrs.update(fs=echo.fs, compressed=int(echo.compressed),
                 waveform=to_json(dataclasses.asdict(echo.waveform)), medium=to_json(dataclasses.asdict(echo.medium)))
    attrs.update(_scenario_attrs(echo.scenario))
    return xr.Dataset(data_vars, coords, attrs)


def _scenario_attrs(scenario) -> dict:
    """``{"scenario": TOML text}``, or ``{"scenario_missing": why}`` when TOML cannot hold it."""
    if scenario is None:
        return {}
    try:
        return {"scenario": scenario_to_toml(scenario)}
    except TypeError as err:
        log.warning("the echo's scenario is not stored with it: %s", err)
        return {"scenario_missing": str(err)}


def _scenario_of(ds):
    text = ds.attrs.get("scenario")
    if text is None:
        return None
    try:
        return scenario_from_toml(text)
    except ValueError as err:
        raise ValueError(f"the scenario attribute does not describe a scenario: {err}") from None


def _check_kind(ds, kind: str) -> None:
    found = ds.attrs.get("clsas_kind")
    if found != kind:
        raise ValueError(f"the dataset's clsas_kind attribute is {found!r}, expected {kind!r}")
    fmt = int(ds.attrs.get("clsas_format", -1))
    if fmt != FORMAT:
        raise ValueError(f"clsas_format {fmt} is not the format this clsas reads ({FORMAT})")


def _need(ds, names, kind: str) -> None:
    missing = [n for n in names if n not in ds.variables]
    if missing:
        raise ValueError(f"the {kind} dataset lacks {missing}")


def _json_attr(ds, name: str):
    try:
        return json.loads(ds.attrs[name])
    except KeyError:
        raise ValueError(f"the dataset lacks the attribute {name!r}") from None
    except (TypeError, json.JSONDecodeError) as err:
        raise ValueError(f"the attribute {name!r} is not valid JSON ({err})") from None


def echo_from_xarray(ds) -> EchoData:
    """The EchoData of a Dataset made by :func:`echo_to_xarray`; ValueError saying what is missing or wrong."""
    _check_kind(ds, "EchoData")
    _need(ds, ("echo", "rx", "eta", "t0", "tx_pos", "rx_pos", "rx_tau"), "EchoData")
    try:
        waveform = Waveform(**_json_attr(ds, "waveform"))
        medium = Medium(**_json_attr(ds, "medium"))
    except TypeError as err:
        raise ValueError(f"the waveform or medium attribute does not describe one: {err}") from None
    echo = ds["echo"].transpose("rx", "pulse", "sample")
    return EchoData(
        data=echo.values, eta=ds["eta"].values, t0=ds["t0"].values, fs=float(ds.attrs["fs"]),
        tx_pos=ds["tx_pos"].transpose("pulse", "xyz").values,
        rx_pos=ds["rx_pos"].transpose("rx", "pulse", "node", "xyz").values,
        rx_tau=ds["rx_tau"].transpose("rx", "node").values, waveform=waveform, medium=medium,
        receivers=tuple(str(r) for r in ds["rx"].values), compressed=bool(int(ds.attrs.get("compressed", 0))),
        provenance=_json_attr(ds, "provenance"), scenario=_scenario_of(ds))


def plane_height(image: Image):
    """z of the horizontal plane that ``image.positions`` lie on, exactly as the x and y axes
    place them (so positions can be rebuilt bit for bit); None when they do not."""
    pos = image.positions
    if pos is None or image.dims != ("y", "x") or pos.size == 0:
        return None
    z = pos[0, 0, 2]
    if (np.array_equal(pos[..., 0], np.broadcast_to(image.axes["x"][None, :], pos.shape[:2]))
            and np.array_equal(pos[..., 1], np.broadcast_to(image.axes["y"][:, None], pos.shape[:2]))
            and np.all(pos[..., 2] == z)):
        return float(z)
    return None


def plane_positions(x, y, z: float) -> np.ndarray:
    """Positions (len(y), len(x), 3) of the horizontal plane z over axes x, y (as Grid.plane)."""
    pos = np.empty((len(y), len(x), 3))
    pos[..., 0] = np.asarray(x)[None, :]
    pos[..., 1] = np.asarray(y)[:, None]
    pos[..., 2] = z
    return pos


def check_image_names(dims) -> None:
    """ValueError unless every dim is a name a NetCDF/zarr file can hold and none is taken."""
    taken = {"image", "positions", "xyz"}
    for d in dims:
        if not isinstance(d, str) or not d or not (d[0].isalpha() or d[0] == "_") \
                or not all(ch.isalnum() or ch in "_-" for ch in d):
            raise ValueError(f"Image.dims: {d!r} cannot name a variable in a clsas file (letters, digits, '_' "
                             "and '-', starting with a letter or '_')")
        if d in taken:
            raise ValueError(f"Image.dims: {d!r} is taken by the file layout ({sorted(taken)})")


def image_to_xarray(image: Image):
    """The xarray.Dataset of ``image`` (layout in the module docstring)."""
    xr = _xarray()
    check_image_names(image.dims)
    coords = {}
    for d in image.dims:
        units, long_name = AXIS_UNITS.get(d, ("1", f"{d} coordinate"))
        coords[d] = (d, image.axes[d], {"units": units, "long_name": long_name})
    data_vars = {"image": (image.dims, image.data, {"long_name": "complex image", "units": "1"})}
    z = plane_height(image)
    layout = "axes"
    if z is not None:
        coords["z"] = ((), z, {"units": "m", "long_name": "height of the image plane (negative below the surface)"})
        layout = "plane"
    elif image.positions is not None:
        coords["xyz"] = ("xyz", np.array(["x", "y", "z"]), {"long_name": "world axis"})
        data_vars["positions"] = (image.dims + ("xyz",), image.positions,
                                  {"long_name": "world position of each pixel", "units": "m"})
        layout = "positions"
    attrs = _attrs("Image", f"clsas Image {' x '.join(f'{n} {d}' for d, n in zip(image.dims, image.data.shape))}",
                   image.provenance)
    attrs.update(dims=to_json(list(image.dims)), positions_layout=layout)
    return xr.Dataset(data_vars, coords, attrs)


def image_from_xarray(ds) -> Image:
    """The Image of a Dataset made by :func:`image_to_xarray`; ValueError saying what is missing or wrong."""
    _check_kind(ds, "Image")
    dims = tuple(_json_attr(ds, "dims"))
    _need(ds, ("image",) + dims, "Image")
    data = ds["image"].transpose(*dims).values
    axes = {d: ds[d].values for d in dims}
    layout = ds.attrs.get("positions_layout", "axes")
    positions = None
    if layout == "plane":
        _need(ds, ("z",), "Image")
        positions = plane_positions(axes["x"], axes["y"], float(ds["z"].values))
    elif layout == "positions":
        _need(ds, ("positions",), "Image")
        positions = ds["positions"].transpose(*dims, "xyz").values
    elif layout != "axes":
        raise ValueError(f"positions_layout {layout!r} is not one of 'axes', 'plane', 'positions'")
    return Image(data=data, dims=dims, axes=axes, provenance=_json_attr(ds, "provenance"), positions=positions)


def to_xarray(obj):
    """The ``xarray.Dataset`` of an EchoData or an Image, with named, united coordinates."""
    if isinstance(obj, EchoData):
        return echo_to_xarray(obj)
    if isinstance(obj, Image):
        return image_to_xarray(obj)
    raise TypeError(f"to_xarray obj: must be an EchoData or an Image, got {type(obj).__name__}")


def from_xarray(ds):
    """EchoData or Image, by the dataset's ``clsas_kind`` attribute."""
    if not isinstance(getattr(ds, "attrs", None), dict) or not hasattr(ds, "data_vars"):
        raise TypeError(f"from_xarray ds: must be an xarray.Dataset made by clsas.to_xarray, got {type(ds).__name__}")
    kind = ds.attrs.get("clsas_kind")
    if kind == "EchoData":
        return echo_from_xarray(ds)
    if kind == "Image":
        return image_from_xarray(ds)
    raise ValueError(f"from_xarray ds: the dataset's clsas_kind attribute is {kind!r}; expected 'EchoData' or 'Image'")
