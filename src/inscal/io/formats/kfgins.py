"""KF-GINS (i2Nav, Wuhan University) IMU text and the ``imunoise`` block of its YAML configuration.

The IMU file: one sample per line, 7 numbers separated by blanks or commas (KF-GINS reads the first
7 columns, ``imudatalen: 7``)::

    t  dtheta_x dtheta_y dtheta_z  dvel_x dvel_y dvel_z          [s (GNSS seconds of week), rad, m/s]

``t`` is the end of the sample interval (as inscal's records), the increments are in the IMU's
axes, which KF-GINS takes as front-right-down.  Extra columns are ignored, as KF-GINS does.

The ``imunoise`` block (field units of KF-GINS's ``kf-gins.yaml``)::

    imunoise:
      arw: [0.003, 0.003, 0.003]      # deg/sqrt(h)     angle random walk
      vrw: [0.03, 0.03, 0.03]         # m/s/sqrt(h)     velocity random walk
      gbstd: [0.027, 0.027, 0.027]    # deg/h           gyro bias, first-order Gauss-Markov sigma
      abstd: [15.0, 15.0, 15.0]       # mGal            accelerometer bias, Gauss-Markov sigma
      gsstd: [300.0, 300.0, 300.0]    # ppm             gyro scale factor, Gauss-Markov sigma
      asstd: [300.0, 300.0, 300.0]    # ppm             accelerometer scale factor, Gauss-Markov sigma
      corrtime: 4.0                   # h               the correlation time of all six processes

:func:`read_kfgins_noise` reads it as an :class:`~inscal.core.error_model.ImuNoise` (the scale-factor
processes have no counterpart there and are returned apart); ``imudatarate`` [Hz] comes with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inscal.core import units
from inscal.core.error_model import ImuNoise
from inscal.io.files import check_input
from inscal.io.formats.base import Raw, ReadOptions
from inscal.io.mapping import ImportFileError

#: the imunoise keys, their inscal noise field (None: no counterpart), unit kind and KF-GINS field unit
NOISE_KEYS = {
    "arw": ("arw", "arw", "deg/sqrt(h)"),
    "vrw": ("vrw", "vrw", "m/s/sqrt(h)"),
    "gbstd": ("gyro_bias_instability", "rate", "deg/h"),
    "abstd": ("accel_bias_instability", "accel", "mGal"),
    "gsstd": (None, "dimensionless", "ppm"),
    "asstd": (None, "dimensionless", "ppm"),
}


@dataclass(frozen=True)
class KfginsNoise:
    """The ``imunoise`` block: ``noise`` (SI; both bias processes with ``corrtime`` as their correlation
    time), the scale-factor processes' sigmas ``scale_sigma`` (gyro, accel; (3,) each, dimensionless)
    and the file's ``imudatarate`` [Hz] (None when absent)."""

    noise: ImuNoise
    scale_sigma: tuple
    rate_hz: float | None


def read_kfgins_text(path) -> Raw:
    """A KF-GINS IMU text file as a :class:`~inscal.io.formats.base.Raw` block of increments."""
    p = Path(path)
    check_input(p, "file", ImportFileError)
    rows, lines = [], []
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ImportFileError(f"{p}: not a text file (not UTF-8)") from None
    for n, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("#") or s.startswith("%"):
            continue
        cells = s.replace(",", " ").split()
        if len(cells) < 7:
            raise ImportFileError(f"{p}: line {n} has {len(cells)} column(s); KF-GINS IMU text has 7 "
                                  "(t, dtheta x y z [rad], dvel x y z [m/s])")
        try:
            rows.append([float(c) for c in cells[:7]])
        except ValueError:
            bad = next(c for c in cells[:7] if not _is_number(c))
            raise ImportFileError(f"{p}: line {n}: {bad!r} is not a number") from None
        lines.append(n)
    if len(rows) < 2:
        raise ImportFileError(f"{p}: {len(rows)} data row(s); at least 2 samples are needed")
    a = np.asarray(rows, dtype=float)
    labels = tuple(f"{name} (column {k + 2})" for k, name in enumerate(("dthx", "dthy", "dthz", "dvx", "dvy", "dvz")))
    return Raw(a[:, 0].copy(), a[:, 1:4].copy(), a[:, 4:7].copy(), "increments", None, labels,
               np.asarray(lines), "", a[:, 1:7], time_label="time (column 1)",
               time_fix="KF-GINS time is in seconds: divide its first column by {factor} before importing")


def _is_number(c: str) -> bool:
    try:
        float(c)
    except ValueError:
        return False
    return True


def _yaml(p: Path) -> dict:
    from ruamel.yaml import YAML, YAMLError

    check_input(p, "KF-GINS configuration", ImportFileError)
    try:
        doc = YAML(typ="safe", pure=True).load(p.read_text(encoding="utf-8"))
    except (YAMLError, UnicodeDecodeError) as exc:
        raise ImportFileError(f"{p}: not a YAML file ({str(exc).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise ImportFileError(f"{p}: a KF-GINS configuration is a YAML mapping")
    return doc


def read_kfgins_noise(path) -> KfginsNoise:
    """The ``imunoise`` block (and ``imudatarate``) of a KF-GINS configuration file, converted to SI."""
    p = Path(path)
    doc = _yaml(p)
    block = doc.get("imunoise")
    if not isinstance(block, dict):
        raise ImportFileError(f"{p}: no imunoise block")
    missing = [k for k in (*NOISE_KEYS, "corrtime") if k not in block]
    if missing:
        raise ImportFileError(f"{p}: imunoise needs {', '.join(missing)}")
    si, scale = {}, []
    for key, (field, kind, unit) in NOISE_KEYS.items():
        v = np.asarray(block[key], dtype=float) if isinstance(block[key], (list, int, float)) else None
        if v is None or v.shape not in ((), (3,)) or not np.all(np.isfinite(v)) or np.any(v < 0):
            raise ImportFileError(f"{p}: imunoise {key} must be 3 finite non-negative numbers in {unit}, "
                                  f"got {block[key]!r}")
        x = np.broadcast_to(units.to_si(v, unit, kind), (3,)).copy()
        if field is None:
            scale.append(x)
        else:
            si[field] = x
    try:
        tau = float(units.to_si(float(block["corrtime"]), "h", "time"))
    except (TypeError, ValueError):
        raise ImportFileError(f"{p}: imunoise corrtime must be a number of hours, got {block['corrtime']!r}") from None
    if not (np.isfinite(tau) and tau > 0):
        raise ImportFileError(f"{p}: imunoise corrtime must be positive, got {block['corrtime']!r}")
    rate = doc.get("imudatarate")
    if rate is not None:
        try:
            rate = float(rate)
        except (TypeError, ValueError):
            raise ImportFileError(f"{p}: imudatarate must be a number of Hz, got {rate!r}") from None
        if not (np.isfinite(rate) and rate > 0):
            raise ImportFileError(f"{p}: imudatarate must be positive, got {rate!r}")
    noise = ImuNoise(gyro_bias_tau=tau, accel_bias_tau=tau, **si)
    return KfginsNoise(noise, tuple(scale), rate)


def read(src, opts: ReadOptions) -> Raw:
    """The reader of :data:`~inscal.io.formats.REGISTRY` (its configuration, ``--config``, is read apart:
    :func:`read_kfgins_noise`)."""
    return read_kfgins_text(Path(src))


def write(tmp, chunks, info, rows=None) -> None:
    """The export writer of :data:`~inscal.io.formats.REGISTRY`: KF-GINS IMU text, rows ``t dθ dv`` (s, rad,
    m/s) of 17 digits."""
    with open(tmp, "w") as fh:
        for t, dth, dv, _ in chunks:
            np.savetxt(fh, np.column_stack([t, dth, dv]), fmt="%.17g")
