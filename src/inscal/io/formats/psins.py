"""``--format psins``: PSINS raw binary (``.bin``), little-endian rows of 7 float64 (or float32) values
``[dθx dθy dθz dvx dvy dvz t]`` (rad, m/s, s; with ``rates`` the rate form ``[wx wy wz fx fy fz t]``);
a ``.mat`` file given as ``psins`` is read as :mod:`inscal.io.formats.mat`."""

from __future__ import annotations

from pathlib import Path as FsPath

import numpy as np

from inscal.io.formats.base import Raw, ReadOptions, file_bytes, rows7
from inscal.io.formats.mat import read_mat
from inscal.io.mapping import ImportFileError


def read_psins_bin(path, dtype: str = "float64", rates: bool = False) -> Raw:
    """PSINS raw binary: little-endian rows of 7 float64 (or float32) values."""
    p = FsPath(path)
    if dtype not in ("float64", "float32"):
        raise ImportFileError(f"--dtype must be float64 or float32, got {dtype!r}")
    b = file_bytes(p)
    item = 8 if dtype == "float64" else 4
    row = 7 * item
    if len(b) % row:
        other = "float32" if dtype == "float64" else "float64"
        raise ImportFileError(f"{p}: {len(b)} bytes is not a whole number of 7-value {dtype} rows ({row} bytes each; "
                              f"truncated, or {other}?)")
    a = np.frombuffer(b, dtype="<f8" if item == 8 else "<f4").reshape(-1, 7)
    hint = ""
    if _plausible_rows(b, 12 - item):  # the other width reads as a clean time base: say so on time errors
        hint = " (is the file float32? try --dtype float32)" if dtype == "float64" else " (is the file float64? drop --dtype float32)"
    return rows7(a, str(p), rates, hint)


def _plausible_rows(b: bytes, item: int) -> bool:
    """Whether ``b`` read as 7-value rows of ``item``-byte floats has a finite, increasing, uniform time column."""
    if len(b) % (7 * item) or len(b) < 3 * 7 * item:
        return False
    with np.errstate(all="ignore"):
        t = np.frombuffer(b, dtype="<f8" if item == 8 else "<f4").reshape(-1, 7)[:, 6].astype(float)
        st = np.diff(t)
        med = np.median(st) if st.size else 0.0
        return bool(np.all(np.isfinite(t)) and med > 0 and np.all(np.abs(st - med) < 0.01 * med))



def read(src, opts: ReadOptions) -> Raw:
    """The reader of :data:`~inscal.io.formats.REGISTRY`: a ``.bin`` file, or a ``.mat`` one by its name."""
    p = FsPath(src)
    return read_mat(p, opts.variable, opts.rates) if p.suffix.lower() == ".mat" else read_psins_bin(p, opts.dtype, opts.rates)


def write(tmp, chunks, info, rows=None) -> None:
    """The export writer of :data:`~inscal.io.formats.REGISTRY`: little-endian float64 rows ``[dθ dv t]``."""
    with open(tmp, "wb") as fh:
        for t, dth, dv, _ in chunks:
            np.ascontiguousarray(np.column_stack([dth, dv, t]), dtype="<f8").tofile(fh)
