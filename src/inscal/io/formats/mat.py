"""``--format mat``: a MATLAB ``.mat`` file (v4-v7 through scipy.io, v7.3 through h5py) holding the PSINS
rows ``[dθ dv t]`` (or rates, ``rates``): the first 2-D numeric variable with 7 columns, or the one named."""

from __future__ import annotations

from pathlib import Path as FsPath

import h5py
import numpy as np

from inscal.io.formats.base import Raw, ReadOptions, file_bytes, rows7
from inscal.io.mapping import ImportFileError


def _mat_variables(p: FsPath) -> list[tuple[str, np.ndarray]]:
    import scipy.io

    try:
        d = scipy.io.loadmat(str(p))
    except NotImplementedError:  # MATLAB v7.3 = HDF5, arrays stored transposed

        out = []
        with h5py.File(p, "r") as h5:
            for k, v in h5.items():
                if isinstance(v, h5py.Dataset) and not k.startswith("#"):
                    a = v[()]
                    out.append((k, a.T if np.ndim(a) == 2 else a))
        return out
    except Exception as exc:  # scipy raises assorted errors (ValueError, struct.error, ...) on files that are not MAT
        raise ImportFileError(f"{p}: not a readable MAT file ({type(exc).__name__}: {exc})") from None
    return [(k, v) for k, v in d.items() if not k.startswith("__")]


def _describe(a) -> str:
    a = np.asarray(a)
    return f"{'x'.join(map(str, a.shape))} {a.dtype}"


def read_mat(path, variable: str | None = None, rates: bool = False) -> Raw:
    """A MAT file: the first 2-D numeric variable with 7 columns, or ``variable``."""
    p = FsPath(path)
    file_bytes(p)
    vars_ = _mat_variables(p)

    def usable(a) -> bool:
        return isinstance(a, np.ndarray) and a.ndim == 2 and a.shape[1] == 7 and a.dtype.kind in "fiu"

    if variable is not None:
        found = dict(vars_)
        if variable not in found:
            raise ImportFileError(f"{p}: no variable {variable!r}; variables: {', '.join(found) or 'none'}")
        a = found[variable]
        if not usable(a):
            raise ImportFileError(f"{p}: variable {variable!r} is {_describe(a)}; expected an N x 7 floating-point array")
        name = variable
    else:
        cand = [(k, v) for k, v in vars_ if usable(v)]
        if not cand:
            listing = ", ".join(f"{k} ({_describe(v)})" for k, v in vars_) or "none"
            raise ImportFileError(f"{p}: no 2-D numeric variable with 7 columns [dθ dv t]; variables: {listing}")
        name, a = cand[0]
    if a.dtype.kind in "iu":
        raise ImportFileError(f"{p}: variable {name!r} holds integers ({a.dtype}): PSINS rows are floating-point "
                              "rad, m/s and s (raw counts: export them as csv and import with a mapping)")
    return rows7(a, f"{p} variable {name!r}", rates)



def read(src, opts: ReadOptions) -> Raw:
    """The reader of :data:`~inscal.io.formats.REGISTRY`."""
    return read_mat(FsPath(src), opts.variable, opts.rates)


def write(tmp, chunks, info, rows=None) -> None:
    """The export writer of :data:`~inscal.io.formats.REGISTRY`: the variable ``imu``, N x 7 rows ``[dθ dv t]``."""
    import scipy.io

    parts = [np.column_stack([dth, dv, t]) for t, dth, dv, _ in chunks]
    with open(tmp, "wb") as fh:
        scipy.io.savemat(fh, {"imu": np.concatenate(parts)})
