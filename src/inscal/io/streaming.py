"""A record read piece by piece, its samples staying on disk: chunks of the whole record
(:func:`iter_chunks`), a window of time located by bisection and streamed (:func:`record_window`,
:func:`iter_window`), and a record whose arrays are read on demand (:func:`open_record`,
:class:`LazyArray`), each chunk checked as :func:`~inscal.io.recordfile.read_record` checks a whole record.
"""

from __future__ import annotations

import bisect
import math
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from inscal.core.cancel import check_cancel
from inscal.io.recordfile import (
    check_datasets,
    open_checked,
    read_meta,
    read_rate,
    read_temperature,
    reading,
)
from inscal.io.records import DataFileError, Record, validate_arrays


def iter_chunks(path, chunk_size: int = 1 << 19) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]]:
    """The samples of a record in chunks, each validated, one chunk in memory (multi-day records).

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    chunk_size : int
        Samples per chunk.

    Yields
    ------
    tuple of numpy.ndarray
        ``(time, dtheta, dvel, gimbal)`` of each chunk (``gimbal`` None when the record has none).

    Raises
    ------
    DataFileError
        A file that is not a readable record, samples that cannot be read, NaN/inf, or a time grid
        that is not uniform (across chunk boundaries too).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, iter_chunks, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> [len(time) for time, dtheta, dvel, gimbal in iter_chunks("still.h5", chunk_size=64)]
    [64, 64, 64, 8]
    """
    with open_checked(path) as h5, reading(path):
        rate = read_rate(h5, path)
        n = h5["time"].shape[0]
        last_t = None
        for k0 in range(0, n, chunk_size):
            check_cancel()
            sl = slice(k0, min(n, k0 + chunk_size))
            try:
                t = h5["time"][sl]
                dth = h5["dtheta"][sl]
                dv = h5["dvel"][sl]
                g = h5["gimbal"][sl] if "gimbal" in h5 else None
            except OSError as exc:
                raise DataFileError(f"{path}: cannot read samples {sl.start}..{sl.stop} (truncated file?): {exc}") from None
            tt = t if last_t is None else np.concatenate([[last_t], t])
            if tt.shape[0] >= 2:
                validate_arrays(tt, None, None, None, rate, where=f"{path} samples {sl.start}..{sl.stop}")
            for name, a in (("dtheta", dth), ("dvel", dv), ("gimbal", g)):
                if a is not None and not np.all(np.isfinite(a)):
                    raise DataFileError(f"{path}: {name} has NaN/inf in samples {sl.start}..{sl.stop}")
            last_t = t[-1]
            yield t, dth, dv, g



@dataclass(frozen=True)
class Window:
    """The samples ``i0 .. i1 - 1`` of a record whose time lies in ``(start_s, stop_s]`` (:func:`record_window`).

    Parameters
    ----------
    path : str
        The record.
    n_total : int
        The record's number of samples.
    rate_hz : float
        Its sample rate [Hz].
    i0, i1 : int
        The first sample of the window and one past its last.
    has_gimbal : bool
        Whether the record has gimbal angles.

    Examples
    --------
    >>> from inscal.io import Window
    >>> Window("still.h5", 200, 100.0, 50, 150, False).n
    100
    """

    path: str
    n_total: int
    rate_hz: float
    i0: int
    i1: int
    has_gimbal: bool

    @property
    def n(self) -> int:
        """The number of samples in the window, ``i1 - i0``."""
        return self.i1 - self.i0


def record_window(path, start_s: float = 0.0, stop_s: float | None = None) -> Window:
    """Locate the samples with ``start_s < time <= stop_s`` by bisection of ``/time`` (a few reads).

    The samples themselves are validated as they are streamed (:func:`iter_window`).

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    start_s : float
        The window's start [s] (excluded).
    stop_s : float, optional
        The window's end [s] (included); None: the end of the record.

    Returns
    -------
    Window
        The indices of the window and the record's size and rate.

    Raises
    ------
    DataFileError
        A file that is not a readable record, datasets of the wrong shape, or a rate that is not positive.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, record_window, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> w = record_window("still.h5", 0.5, 1.0)
    >>> w.i0, w.i1, w.n
    (50, 100, 50)
    """

    with open_checked(path) as h5, reading(path):
        rate = read_rate(h5, path)
        n = check_datasets(h5, path)
        if not (math.isfinite(rate) and rate > 0):
            raise DataFileError(f"{path}: rate_hz must be positive, got {rate}")
        t = h5["time"]
        try:
            i0 = bisect.bisect_right(t, start_s)
            i1 = n if stop_s is None else bisect.bisect_right(t, stop_s)
        except OSError as exc:
            raise DataFileError(f"{path}: cannot read /time (truncated file?): {exc}") from None
        return Window(str(path), n, rate, i0, max(i0, i1), "gimbal" in h5)


def iter_window(path, names: tuple[str, ...], i0: int, i1: int, chunk_size: int = 1 << 18) -> Iterator[tuple]:
    """Stream some datasets of a record over samples ``i0 .. i1 - 1``, one chunk at a time, checked.

    Each chunk is checked for finite values, and ``/time`` for a uniform grid at ``rate_hz``
    (across chunk boundaries too) when ``"time"`` is among ``names``.

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    names : tuple of str
        The datasets to read ("time", "dtheta", "dvel", "gimbal").
    i0, i1 : int
        The first sample and one past the last (e.g. from :func:`record_window`).
    chunk_size : int
        Samples per chunk.

    Yields
    ------
    tuple of numpy.ndarray
        One array per name (None for an absent gimbal).

    Raises
    ------
    DataFileError
        Samples that cannot be read, NaN/inf, or a time grid that is not uniform.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, iter_window, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> [float(time[0]) for (time,) in iter_window("still.h5", ("time",), 50, 150, chunk_size=50)]
    [0.51, 1.01]
    """
    with open_checked(path) as h5, reading(path):
        rate = read_rate(h5, path)
        check_datasets(h5, path)
        last_t = None
        for k0 in range(i0, i1, chunk_size):
            check_cancel()
            sl = slice(k0, min(i1, k0 + chunk_size))
            try:
                out = tuple(h5[nm][sl] if nm in h5 else None for nm in names)
            except OSError as exc:
                raise DataFileError(f"{path}: cannot read samples {sl.start}..{sl.stop} (truncated file?): {exc}") from None
            for nm, a in zip(names, out):
                if a is None:
                    continue
                if not np.all(np.isfinite(a)):
                    bad = ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
                    raise DataFileError(f"{path}: {nm} has NaN/inf value(s), first at sample {sl.start + int(np.argmax(bad))}")
                if nm == "time":
                    tt = a if last_t is None else np.concatenate([[last_t], a])
                    if tt.shape[0] >= 2:
                        validate_arrays(tt, None, None, None, rate, where=f"{path} samples {sl.start}..{sl.stop}")
                    last_t = a[-1]
            yield out


class LazyArray:
    """A record dataset read on demand, the samples staying on disk.

    ``a[i:j]`` reads those rows, ``a[::step]`` / ``a[::step, k]`` reads the decimated rows chunk by
    chunk (contiguous reads, cached per step) for plots; ``np.asarray(a)`` reads it all (avoid it on
    long records).

    Parameters
    ----------
    ds : h5py.Dataset
        The dataset of an open record.
    chunk_size : int
        Rows per contiguous read when decimating.
    where : str
        The file, for the messages of a damaged one (default: the dataset's name).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, open_record, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> with open_record("still.h5") as rec:
    ...     lazy = rec.time
    ...     print(type(lazy).__name__, len(lazy), lazy[::50].tolist())
    LazyArray 200 [0.01, 0.51, 1.01, 1.51]
    """

    def __init__(self, ds, chunk_size: int = 1 << 18, where=""):
        self._ds, self._chunk, self._dec, self._where = ds, chunk_size, {}, where or ds.name
        self.shape, self.dtype, self.ndim = ds.shape, ds.dtype, ds.ndim

    def __len__(self) -> int:
        return int(self.shape[0])

    def decimated(self, step: int) -> np.ndarray:
        """Rows 0, step, 2 step, ... (read in contiguous chunks)."""
        if step not in self._dec:
            n, parts = self.shape[0], []
            block = max(step, (self._chunk // step) * step)
            for a in range(0, n, block):
                check_cancel()
                with reading(self._where):
                    parts.append(self._ds[a:min(n, a + block)][::step].copy())  # not a view of the block
            self._dec[step] = np.concatenate(parts) if parts else self._ds[0:0]
        return self._dec[step]

    def __getitem__(self, key):
        first, rest = (key[0], key[1:]) if isinstance(key, tuple) else (key, ())
        if isinstance(first, slice) and first.step not in (None, 1) and first.start is None and first.stop is None:
            d = self.decimated(int(first.step))
            return d[(slice(None), *rest)] if rest else d
        with reading(self._where):
            return self._ds[key]

    def __array__(self, dtype=None, copy=None):
        a = self._ds[()]
        return a if dtype is None else a.astype(dtype)


@contextmanager
def open_record(path, validate: bool = True, chunk_size: int = 1 << 19):
    """A :class:`Record` whose samples stay on disk, for reports of multi-day records in bounded memory.

    Its arrays are :class:`LazyArray`; the file is open inside the ``with`` block.

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    validate : bool
        First stream the samples once through the checks of :func:`~inscal.io.recordfile.read_record`
        (finite values, uniform time), one chunk at a time.
    chunk_size : int
        Samples per chunk of that check.

    Yields
    ------
    Record
        The record, with :class:`LazyArray` samples.

    Raises
    ------
    DataFileError
        A file that is not a readable record, a rate that is not positive, fewer than 2 samples, or
        samples that fail the checks.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, open_record, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> with open_record("still.h5") as rec:
    ...     print(rec.n_samples, rec.dtheta[10:12].shape)
    200 (2, 3)
    """
    with open_checked(path) as h5:
        with reading(path):
            n = check_datasets(h5, path)
            rate = read_rate(h5, path)
            if not (math.isfinite(rate) and rate > 0):
                raise DataFileError(f"{path}: rate_hz must be positive, got {rate}")
            if n < 2:
                raise DataFileError(f"{path}: fewer than 2 samples")
            site, p, truth = read_meta(h5, path)
            scen = str(h5.attrs.get("scenario", ""))
            temp = read_temperature(h5, path)
            if validate:
                for _ in iter_chunks(path, chunk_size):
                    pass
            lazy = {k: LazyArray(h5[k], where=path) for k in ("time", "dtheta", "dvel", "gimbal") if k in h5}
        yield Record(lazy["time"], lazy["dtheta"], lazy["dvel"], lazy.get("gimbal"), rate, site, p, truth, scen, str(path),
                     temp)


