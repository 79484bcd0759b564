"""Calibration parameter files (TOML), written by ``inscal calibrate --out``.

Layout (``schema_version`` :data:`PARAM_SCHEMA_VERSION`)::

    kind = "inscal-parameters"
    schema_version = 1
    inscal_version = "0.1.0"
    method = "n25"
    created = "2025-01-01T00:00:00Z"        # UTC
    data_file = "run.h5"                    # optional
    data_hash = "sha256:..."                # optional: io.file_hash of the data file

    [parameters.accel_bias]                 # names and field units of errors.PARAMETERS
    value = [50.0, -80.0, 100.0]
    sigma = [1.2, 1.1, 0.9]                 # 1 sigma (nan: held fixed)
    unit = "ug"

Values are in the field units of :data:`inscal.errors.PARAMETERS` (ppm, arcsec, deg/h,
ug); ``load_params`` converts back to SI.  Files are written to a temporary name and
renamed, so an existing file is never half-overwritten, and never overwritten unless asked.
"""

from __future__ import annotations

import datetime as _dt
import tomllib
from pathlib import Path as FsPath

import numpy as np
import tomli_w

from . import __version__
from .errors import PARAMETERS, GimbalErrors, ImuErrors, errors_from_field

PARAM_SCHEMA_VERSION = 1
KIND = "inscal-parameters"


class ParamFileError(ValueError):
    """A parameter file that cannot be read or written, with the reason."""


def _atomic_write_text(path: FsPath, text: str, overwrite: bool) -> None:
    from .io import atomic_path

    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")


def params_document(result, data_file: str | None = None, data_hash: str | None = None,
                    metadata: dict | None = None, truth=None) -> dict:
    """The TOML document (a dict) for a :class:`inscal.calibrate.CalibrationResult`."""
    doc = {
        "kind": KIND,
        "schema_version": PARAM_SCHEMA_VERSION,
        "inscal_version": __version__,
        "method": result.method,
        "created": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    }
    if data_file is not None:
        doc["data_file"] = str(data_file)
    if data_hash is not None:
        doc["data_hash"] = str(data_hash)
    if metadata:
        doc["metadata"] = {str(k): v for k, v in metadata.items() if v is not None}
    doc["parameters"] = result.to_field(truth)
    return doc


def save_params(path, result, data_file: str | None = None, data_hash: str | None = None,
                metadata: dict | None = None, overwrite: bool = False, truth=None) -> None:
    """Write ``result`` to ``path`` (TOML, atomic).  Refuses to overwrite unless ``overwrite``."""
    doc = params_document(result, data_file, data_hash, metadata, truth)
    try:
        text = tomli_w.dumps(doc)
    except (TypeError, ValueError) as exc:
        raise ParamFileError(f"cannot encode the parameters as TOML: {exc}") from None
    _atomic_write_text(FsPath(path), text, overwrite)


def load_params(path) -> tuple[ImuErrors, GimbalErrors, dict]:
    """Read a parameter file: ``(ImuErrors, GimbalErrors, metadata)`` (SI).

    ``metadata`` holds ``method``, ``created``, ``data_file``, ``data_hash``,
    ``schema_version``, ``estimated`` (names in the file) and ``sigma`` (SI arrays).
    Parameters not in the file are zero.  Raises :class:`ParamFileError` with the reason.
    """
    p = FsPath(path)
    if not p.is_file():
        raise ParamFileError(f"{p}: no such parameter file")
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ParamFileError(f"{p}: not a valid TOML file ({exc})") from None
    if doc.get("kind") != KIND:
        raise ParamFileError(f"{p}: not an inscal parameter file (kind = {doc.get('kind')!r}, expected {KIND!r})")
    ver = doc.get("schema_version")
    if not isinstance(ver, int):
        raise ParamFileError(f"{p}: missing or invalid schema_version")
    if ver > PARAM_SCHEMA_VERSION:
        raise ParamFileError(f"{p}: schema_version {ver} is newer than this inscal supports ({PARAM_SCHEMA_VERSION}); "
                             "upgrade inscal")
    if ver < 1:
        raise ParamFileError(f"{p}: unsupported schema_version {ver}")
    params = doc.get("parameters")
    if not isinstance(params, dict) or not params:
        raise ParamFileError(f"{p}: no [parameters] section")
    values, sigma = {}, {}
    from . import units

    for name, entry in params.items():
        if name not in PARAMETERS:
            raise ParamFileError(f"{p}: unknown parameter {name!r}; known: {', '.join(PARAMETERS)}")
        if not isinstance(entry, dict) or "value" not in entry or "unit" not in entry:
            raise ParamFileError(f"{p}: parameter {name} needs 'value' and 'unit'")
        kind, shape = PARAMETERS[name][2], PARAMETERS[name][4]
        val = np.squeeze(np.asarray(entry["value"], dtype=float))
        if val.shape != shape and not (shape == () and val.shape == ()):
            raise ParamFileError(f"{p}: parameter {name} has shape {list(val.shape)}, expected {list(shape)}")
        values[name] = {"value": val.tolist(), "unit": entry["unit"]}
        if "sigma" in entry:
            try:
                sigma[name] = units.to_si(np.squeeze(np.asarray(entry["sigma"], dtype=float)), entry["unit"], kind)
            except (units.UnitError, ValueError, TypeError) as exc:
                raise ParamFileError(f"{p}: parameter {name} sigma: {exc}") from None
    try:
        imu, gim = errors_from_field(values)
    except ValueError as exc:
        raise ParamFileError(f"{p}: {exc}") from None
    meta = {k: doc.get(k) for k in ("method", "created", "data_file", "data_hash", "inscal_version")}
    meta.update(schema_version=ver, estimated=tuple(params), sigma=sigma, metadata=doc.get("metadata", {}))
    if not isinstance(meta["method"], str):
        raise ParamFileError(f"{p}: missing 'method'")
    for n, s in sigma.items():
        if np.any(np.asarray(s) < 0) or not np.all(np.isnan(s) | np.isfinite(s)):
            raise ParamFileError(f"{p}: parameter {n} has an invalid sigma")
    return imu, gim, meta
