"""Writing a Dataset to NetCDF4 or zarr, and reading it back slab by slab to check it.

xarray writes a NumPy-backed variable chunk by chunk (h5py and zarr compress one chunk at a
time), so the write itself holds little beyond the object; the check reads the file back one
slab (a few chunks, :data:`SLAB_BYTES`) at a time and compares it bit for bit with what was
written, so a save never holds a second copy of the data (``tests/test_io.py`` measures the
peak).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from ...errors import DataFileError
from .target import is_zarr

CHUNK_BYTES = 4 << 20  # target size of one stored chunk, bytes
#: HDF5 format bounds of a NetCDF file: 1.8's object headers carry checksums, so a flipped bit
#: in the file's structure is an error on read (with the oldest format, HDF5 could read a damaged
#: attribute for ever); HDF5 1.8 and later (every netCDF-4 library) read them
NETCDF_LIBVER = ("v108", "latest")
SLAB_BYTES = 4 << 20  # read back and compared at a time, bytes (whole chunks)
#: chunks zarr-python 3 encodes or decodes at once, and its codec threads (its defaults, 10 and
#: one per core, hold that many chunks and their compressed copies while a store is written)
ZARR_CONCURRENCY = 2
ZARR_THREADS = 1


def chunk_shape(shape: tuple, itemsize: int, target: int = CHUNK_BYTES) -> tuple:
    """Chunk shape of about ``target`` bytes: whole trailing axes, the leading axes cut."""
    chunks = list(shape)
    for axis in range(len(shape)):
        rest = itemsize * int(np.prod(chunks[axis + 1:], dtype=np.int64))
        chunks[axis] = max(1, min(shape[axis], target // max(rest, 1)))
        if rest * chunks[axis] <= target and chunks[axis] < shape[axis]:
            break
    return tuple(max(1, c) for c in chunks)


def no_zarr_compressor() -> dict:
    """The zarr encoding key that turns compression off (zarr-python 3 renamed it)."""
    import zarr

    return {"compressors": None} if int(zarr.__version__.split(".")[0]) >= 3 else {"compressor": None}


def encoding(ds, zarr: bool, level: int) -> dict:
    """Chunks (about :data:`CHUNK_BYTES`), compression and checksums of every variable of
    ``ds``: NetCDF chunks carry a Fletcher-32 checksum, zarr chunks a CRC-32 (numcodecs), so a
    flipped bit in a chunk is an error on read, compressed or not."""
    enc = {}
    for name, var in ds.variables.items():
        if var.dtype.kind == "O":
            continue
        chunks = chunk_shape(var.shape, var.dtype.itemsize) if var.ndim else None
        if zarr:
            import numcodecs

            enc[name] = {"filters": [numcodecs.CRC32()], **({"chunks": chunks} if chunks else {}),
                         **({} if level else no_zarr_compressor())}
        elif chunks and var.dtype.kind not in "US":
            enc[name] = {"chunksizes": chunks, "fletcher32": True}
            if level:
                enc[name].update(compression="gzip", compression_opts=level, shuffle=True)
    return enc


def write(ds, path: Path, level: int) -> None:
    """``ds`` to ``path`` (NetCDF4, or a zarr v2 store with every chunk written, even those
    all zero: a missing chunk then means a damaged store); :func:`clsas.atomic.replace` syncs it
    to the disk before moving it in place."""
    if is_zarr(path):
        with zarr_limits():
            ds.to_zarr(path, mode="w-", encoding=encoding(ds, True, level), consolidated=True, zarr_format=2,
                       write_empty_chunks=True)
    else:
        from xarray.backends import H5NetCDFStore

        store = H5NetCDFStore.open(str(path), mode="w", driver_kwds={"libver": NETCDF_LIBVER})
        try:
            ds.dump_to_store(store, encoding=encoding(ds, False, level))
        finally:
            store.close()


def verify(ds, back, path: Path) -> None:
    """DataFileError naming ``path`` unless the Dataset ``back`` (the file, opened lazily)
    holds every variable and attribute of ``ds`` bit for bit; compared slab by slab."""
    missing = sorted(set(ds.variables) - set(back.variables))
    if missing:
        raise DataFileError(f"{path}: the file read back lacks {missing}")
    for key, value in ds.attrs.items():
        if key not in back.attrs or not _equal(back.attrs[key], value):
            raise DataFileError(f"{path}: the file read back has another attribute {key!r}")
    for name, var in ds.variables.items():
        stored = back.variables[name]
        if stored.shape != var.shape or any(not _equal(stored.attrs.get(k), v) for k, v in var.attrs.items()):
            raise DataFileError(f"{path}: the file read back has another {name!r} (shape or attributes)")
        for part in slabs(var.shape, var.dtype.itemsize):
            if not _equal(stored[part].values, var[part].values):
                raise DataFileError(f"{path}: the file read back differs from the data written in {name!r}")


def zarr_limits():
    """A context in which zarr works on at most :data:`ZARR_CONCURRENCY` chunks at once, with
    :data:`ZARR_THREADS` codec threads."""
    import zarr

    if int(zarr.__version__.split(".")[0]) >= 3:
        return zarr.config.set({"async.concurrency": ZARR_CONCURRENCY, "threading.max_workers": ZARR_THREADS})
    return contextlib.nullcontext()


def slabs(shape: tuple, itemsize: int):
    """Index tuples covering an array of ``shape`` in whole-chunk blocks of about :data:`SLAB_BYTES`."""
    if not shape:
        yield ()
        return
    chunks = list(chunk_shape(shape, itemsize))
    cut = next((axis for axis, (c, n) in enumerate(zip(chunks, shape)) if c < n), None)
    if cut is not None:  # whole chunks along the cut axis, as many as fit a slab
        per_chunk = itemsize * int(np.prod(chunks, dtype=np.int64))
        chunks[cut] = min(shape[cut], chunks[cut] * max(1, SLAB_BYTES // max(per_chunk, 1)))
    counts = [-(-n // c) if n else 0 for n, c in zip(shape, chunks)]
    for index in np.ndindex(*counts):
        yield tuple(slice(i * c, min((i + 1) * c, n)) for i, c, n in zip(index, chunks, shape))


def _equal(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind in "OUS" or b.dtype.kind in "OUS":
        return a.shape == b.shape and all(str(x) == str(y) for x, y in zip(a.ravel().tolist(), b.ravel().tolist()))
    return a.shape == b.shape and np.array_equal(a, b)


def zarr_array(store: Path, name: str):
    """Array ``name`` of the zarr store ``store`` opened for writing parts of it, set to write
    every chunk, even one all zero (zarr-python 3 skips those by default; a store read by
    :func:`clsas.load` must have all its chunks)."""
    import zarr

    if int(zarr.__version__.split(".")[0]) >= 3:  # open_array's config= is not kept (zarr 3.1.6): with_config
        return zarr.open_array(store=str(store), path=name, mode="r+").with_config({"write_empty_chunks": True})
    return zarr.open_array(str(store), path=name, mode="r+", write_empty_chunks=True)
