"""Calibration parameter files (TOML), written by ``inscal calibrate --out``.

Layout (``schema_version`` :data:`PARAM_SCHEMA_VERSION`)::

    kind = "inscal-parameters"
    schema_version = 1
    inscal_version = "0.1.0"
    method = "n25"
    created = "2025-01-01T00:00:00Z"        # UTC
    data_file = "run.h5"                    # optional
    data_hash = "sha256:..."                # optional: io.file_hash of the data file

    [metadata]                              # optional, free-form; inscal calibrate writes
    scenario = "n25"                        # the record's scenario and, when the record has
    imu_serial = "FOG-0042"                 # one, its IMU serial (compensate / navigate warn
                                            # when they differ from the record's)

    [parameters.accel_bias]                 # names and field units of errors.PARAMETERS
    value = [50.0, -80.0, 100.0]
    sigma = [1.2, 1.1, 0.9]                 # 1 sigma reported (nan: held fixed)
    sigma_formal = [0.02, 0.02, 0.02]       # optional: the formal 1 sigma, present when the
    unit = "ug"                             # reported one was scaled (inconsistent fit)

    [thermal]                               # optional: the thermal model (inscal.core.thermal)
    t_ref = 20.0                            # degC; the [parameters] are the errors at t_ref
    t_min = -40.0                           # the range the model was calibrated over (degC)
    t_max = 60.0
    out_of_range = "warn"                   # or "clamp", "error": compensation outside the range
    sensor = ""                             # the temperature sensor ("": mean of the record's)
    [[thermal.terms.gyro_bias]]             # one table per order, unit <unit>/degC^order
    order = 1
    value = [0.002, -0.0015, 0.0025]
    sigma = [1e-4, 1e-4, 1e-4]
    unit = "deg/h/degC"
    [thermal.fit]                           # optional: the fit of the thermal polynomials

    [fit]                                   # optional (window-mean methods): the fit of the model
    chi2 = 1.9e8                            # to the window means (calibrate.result.fit_statistics)
    dof = 86
    expected_chi2 = 86.0                    # > dof for estimators that are not least squares
    p_value = 0.0
    consistent = false                      # p >= 0.001
    scale = 1491.6                          # sqrt(chi2 / expected_chi2) if inconsistent, else 1
    cause = "unmodelled accelerometer terms ..."   # only when inconsistent
    note = "fit inconsistent: ..."                 # the one-line note, only when inconsistent
    [fit.channels.accel]                    # chi2, dof, expected_chi2, p_value, scale, systematic
    [[fit.residuals]]                       # per window: index, label, RMS of the normalised
    window = 0                              # gyro and accelerometer residuals
    label = "static (0.0, 0.0) deg, 1.5-98.5 s"
    gyro = 0.9
    accel = 1366.8

Both additions (schema_version 1 still) are ignored by readers that predate them; files
without them load as before.  The systematic methods report their fit as
``metadata.chi2/dof/p_value`` (innovations).

Values are in the field units of :data:`inscal.core.error_model.PARAMETERS` (ppm, arcsec, deg/h,
ug); ``load_params`` converts back to SI.  Files are written to a temporary name and
renamed, so an existing file is never half-overwritten, and never overwritten unless asked.
"""

from __future__ import annotations

import datetime as _dt
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

from inscal import __version__
from inscal.core import units
from inscal.core.error_model import (
    PARAMETERS,
    GimbalErrors,
    ImuErrors,
    errors_from_field,
)
from inscal.core.thermal import thermal_from_field, thermal_to_field
from inscal.io.files import atomic_path, check_input, file_hash
from inscal.io.jsonfile import to_jsonable
from inscal.io.records import record_attrs

#: version of the parameter file layout (``schema_version``)
PARAM_SCHEMA_VERSION = 1
KIND = "inscal-parameters"


class ParamFileError(ValueError):
    """A parameter file that cannot be read or written, with the reason."""


_IMU_LINEAR = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
               "accel_bias")
#: ``method`` of a parameter file not written by a calibration: true parameters of a simulation
#: (``truth``), values typed in by hand (``manual``) or taken from another tool (``external``)
HAND_METHODS = ("truth", "manual", "external")
#: the tables a file written by each method always has (a file written by inscal that misses one
#: was edited or cut: loading it would silently take that term as zero)
REQUIRED: dict[str, tuple[str, ...]] = {
    "six-position": _IMU_LINEAR,
    "twelve-position": _IMU_LINEAR,
    "n25": _IMU_LINEAR + ("gimbal_nonorthogonality", "mount_attitude"),
    "joint": _IMU_LINEAR + ("gimbal_nonorthogonality", "mount_attitude"),
    "systematic51": _IMU_LINEAR,
    "systematic30": _IMU_LINEAR,
}

#: plausibility limits in field units: a value beyond one is a unit or typing mistake
LIMITS: dict[str, tuple[float, str]] = {
    "gyro_scale_factor": (1e5, "ppm"),
    "accel_scale_factor": (1e5, "ppm"),
    "gyro_misalignment": (36000.0, "arcsec"),
    "accel_misalignment": (36000.0, "arcsec"),
    "accel_bias": (1e6, "ug"),
    "gyro_bias": (1e6, "deg/h"),
    "accel_lever_arm": (100.0, "cm"),
}


def _check_plausible(p, name: str, entry: dict, kind: str) -> None:
    """Non-finite values, and values beyond :data:`LIMITS`, raise :class:`ParamFileError`."""

    raw = np.asarray(entry["value"], dtype=float)
    if not np.all(np.isfinite(raw)):
        raise ParamFileError(f"{p}: parameter {name} has a non-finite value")
    if name not in LIMITS:
        return
    lim, lim_unit = LIMITS[name]
    try:
        si = np.asarray(units.to_si(raw, entry["unit"], kind), dtype=float)
    except (units.UnitError, TypeError, ValueError):
        return  # the unit is reported by errors_from_field
    lim_si = float(units.to_si(lim, lim_unit, kind))
    big = np.abs(si) > lim_si
    if np.any(big):
        worst = float(np.max(np.abs(units.from_si(si, lim_unit))))
        raise ParamFileError(f"{p}: parameter {name} = {worst:.4g} {lim_unit} is implausible (limit {lim:g} {lim_unit}); "
                             "check the value and its unit")


def _atomic_write_text(path: Path, text: str, overwrite: bool) -> None:

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
    fit = getattr(result, "fit", None)
    if fit:
        doc["fit"] = fit_table(fit)
    thermal = getattr(result, "thermal", None)
    if thermal is not None:
        doc["thermal"] = thermal_to_field(thermal, getattr(result, "thermal_sigma", None) or None)
        tfit = result.thermal_fit
        if tfit:
            doc["thermal"]["fit"] = fit_table_any(tfit)
    return doc


def fit_table_any(fit: dict) -> dict:
    """A fit dict as plain TOML types (None and non-finite entries dropped), whatever its keys."""

    def clean(v):
        if isinstance(v, dict):
            return {str(k): clean(x) for k, x in v.items() if x is not None}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v if x is not None]
        return v

    return clean(to_jsonable(fit))


#: keys of a fit dict written to the ``[fit]`` table (large or derived entries are left out)
FIT_KEYS = ("chi2", "dof", "expected_chi2", "dof_effective", "p_value", "consistent", "scale", "cause", "note",
            "channels", "residuals")


def fit_table(fit: dict) -> dict:
    """The ``[fit]`` table of a fit dict (plain TOML types; None and non-finite entries dropped)."""
    return fit_table_any({k: fit[k] for k in FIT_KEYS if k in fit})


def save_params(path, result, data_file: str | None = None, data_hash: str | None = None,
                metadata: dict | None = None, overwrite: bool = False, truth=None) -> None:
    """Write ``result`` to ``path`` (TOML, atomic).  Refuses to overwrite unless ``overwrite``."""
    doc = params_document(result, data_file, data_hash, metadata, truth)
    try:
        text = tomli_w.dumps(doc)
    except (TypeError, ValueError) as exc:
        raise ParamFileError(f"cannot encode the parameters as TOML: {exc}") from None
    _atomic_write_text(Path(path), text, overwrite)


def load_params(path) -> tuple[ImuErrors, GimbalErrors, dict]:
    """Read a parameter file: ``(ImuErrors, GimbalErrors, metadata)`` (SI).

    ``metadata`` holds ``method``, ``created``, ``data_file``, ``data_hash``,
    ``schema_version``, ``estimated`` (names in the file), ``sigma`` (SI arrays, the reported
    1 sigma), ``sigma_formal`` (SI arrays, only for parameters whose sigma was scaled),
    ``metadata`` (the file's ``[metadata]`` table) and ``fit`` (its ``[fit]`` table or None).
    Parameters not in the file are zero.  Raises :class:`ParamFileError` with the reason.
    """
    p = Path(path)
    check_input(p, "parameter file", ParamFileError)
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
    values, sigma, sigma_formal = {}, {}, {}

    for name, entry in params.items():
        if name not in PARAMETERS:
            raise ParamFileError(f"{p}: unknown parameter {name!r}; known: {', '.join(PARAMETERS)}")
        if not isinstance(entry, dict) or "value" not in entry or "unit" not in entry:
            raise ParamFileError(f"{p}: parameter {name} needs 'value' and 'unit'")
        kind, shape = PARAMETERS[name].kind, PARAMETERS[name].shape
        try:
            val = np.squeeze(np.asarray(entry["value"], dtype=float))
        except (TypeError, ValueError):
            raise ParamFileError(f"{p}: parameter {name}: value is not a number or list of numbers") from None
        if val.shape != shape and not (shape == () and val.shape == ()):
            raise ParamFileError(f"{p}: parameter {name} has shape {list(val.shape)}, expected {list(shape)}")
        _check_plausible(p, name, entry, kind)
        values[name] = {"value": val.tolist(), "unit": entry["unit"]}
        for key, dest in (("sigma", sigma), ("sigma_formal", sigma_formal)):
            if key in entry:
                try:
                    dest[name] = units.to_si(np.squeeze(np.asarray(entry[key], dtype=float)), entry["unit"], kind)
                except (units.UnitError, ValueError, TypeError) as exc:
                    raise ParamFileError(f"{p}: parameter {name} {key}: {exc}") from None
    try:
        imu, gim = errors_from_field(values)
    except ValueError as exc:
        raise ParamFileError(f"{p}: {exc}") from None
    meta = {k: doc.get(k) for k in ("method", "created", "data_file", "data_hash", "inscal_version")}
    fit = doc.get("fit")
    if fit is not None and not isinstance(fit, dict):
        raise ParamFileError(f"{p}: [fit] must be a table")
    thermal, thermal_sigma, thermal_fit = None, {}, None
    if "thermal" in doc:
        tdoc = doc["thermal"]
        if not isinstance(tdoc, dict):
            raise ParamFileError(f"{p}: [thermal] must be a table")
        tdoc = dict(tdoc)
        thermal_fit = tdoc.pop("fit", None)
        try:
            thermal, thermal_sigma = thermal_from_field(tdoc)
        except ValueError as exc:
            raise ParamFileError(f"{p}: {exc}") from None
    meta.update(schema_version=ver, estimated=tuple(params), sigma=sigma, sigma_formal=sigma_formal,
                metadata=doc.get("metadata", {}), fit=fit, thermal=thermal, thermal_sigma=thermal_sigma,
                thermal_fit=thermal_fit)
    if not isinstance(meta["method"], str):
        raise ParamFileError(f"{p}: missing 'method'")
    # only files written by inscal (they carry inscal_version) are held to their method's tables;
    # hand-written and pre-0.1 files may list a subset
    required = REQUIRED.get(meta["method"], ()) if doc.get("inscal_version") else ()
    missing = [n for n in required if n not in params]
    if missing:
        raise ParamFileError(f"{p}: method {meta['method']} estimates {', '.join(missing)} but the file has no "
                             f"[parameters.{missing[0]}] table (edited or cut file?)")
    for n, s in list(sigma.items()) + list(sigma_formal.items()):
        if np.any(np.asarray(s) < 0) or not np.all(np.isnan(s) | np.isfinite(s)):
            raise ParamFileError(f"{p}: parameter {n} has an invalid sigma")
    return imu, gim, meta


def provenance_mismatch(data: Path, params: Path, meta: dict, attrs: dict | None = None) -> str | None:
    """One warning line when the parameter file's ``data_hash``, ``metadata.scenario`` or
    ``metadata.imu_serial`` differ from the record's (compared where both have them), else None."""
    attrs = record_attrs(data) if attrs is None else attrs
    pm = meta.get("metadata") or {}
    parts = []
    if meta.get("data_hash"):
        h = file_hash(data)
        if h != meta["data_hash"]:
            parts.append(f"calibrated from another record ({meta.get('data_file') or 'data'} "
                         f"{str(meta['data_hash'])[:19]}..., this one {h[:19]}...)")
    for key, what in (("scenario", "scenario"), ("imu_serial", "IMU serial")):
        a, b = pm.get(key), attrs.get(key)
        if a and b and str(a) != str(b):
            parts.append(f"{what} {a!r} vs the record's {b!r}")
    if not parts:
        return None
    return f"{params} does not match {data}: " + "; ".join(parts)
