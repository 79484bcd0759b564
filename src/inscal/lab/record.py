"""What a caller hands the database for one calibration, built from what it has: the parameter
file's text, the calibration options and their hash, the session of a record file, and the
covariance of a :class:`~inscal.calibrate.CalibrationResult`.

The parameter file's text is the one source of the stored parameters (values, 1 sigma, field
units, fit): the database keeps it byte for byte, so ``inscal db export`` writes back exactly the
file ``inscal calibrate`` wrote, and parses it into rows (:func:`parameter_rows`).
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib

import numpy as np
import tomli_w

from inscal.core import units
from inscal.core.error_model import PARAMETERS, errors_from_field, parameter_components
from inscal.io.files import file_hash
from inscal.io.jsonfile import to_jsonable
from inscal.io.paramfile import (
    KIND,
    PARAM_SCHEMA_VERSION,
    ParamFileError,
    params_document,
)
from inscal.io.recordfile import record_info
from inscal.io.records import record_attrs
from inscal.lab.model import SessionInfo, parse_date


def param_file_text(result, data_file: str | None = None, data_hash: str | None = None,
                    metadata: dict | None = None, truth=None) -> str:
    """The text of the parameter file of a result, exactly what :func:`inscal.io.paramfile.save_params`
    writes for the same arguments.

    Write it with :func:`inscal.io.files.atomic_path` and ``Path.write_text(text, encoding="utf-8")``.

    Parameters
    ----------
    result : CalibrationResult
        The calibration.
    data_file : str, optional
        The record's file name.
    data_hash : str, optional
        The record's hash.
    metadata : dict, optional
        More to write.
    truth : object, optional
        The truth (a simulated record's), to write the errors against it.

    Returns
    -------
    str
        The TOML text.

    Raises
    ------
    ParamFileError
        Parameters that cannot be encoded as TOML.

    Examples
    --------
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> res = CalibrationResult.from_field({"gyro_bias": [0.0] * 3}, {"gyro_bias": [0.0002] * 3}, "six-position")
    >>> text = lab.param_file_text(res)
    >>> text.splitlines()[3], "[parameters.gyro_bias]" in text
    ('method = "six-position"', True)
    """
    try:
        return tomli_w.dumps(params_document(result, data_file, data_hash, metadata, truth))
    except (TypeError, ValueError) as exc:
        raise ParamFileError(f"cannot encode the parameters as TOML: {exc}") from None


def text_hash(text: str) -> str:
    """``sha256:<hex>`` of the UTF-8 bytes of ``text`` (what :func:`inscal.io.files.file_hash` gives for
    the file holding it).

    Parameters
    ----------
    text : str
        The text.

    Returns
    -------
    str
        ``"sha256:"`` and the 64 hex digits of the digest.

    Examples
    --------
    >>> from inscal import lab
    >>> lab.text_hash("")
    'sha256:e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855'
    """
    return "sha256:" + hashlib.sha256(text.encode("utf-8")).hexdigest()


def calibration_options(method: str, *, states: str | None = None, settle: float = 1.0, min_static: float = 20.0,
                        filter_rate_hz: float = 1.0, arw: float | None = None, vrw: float | None = None,
                        gravity: str | None = None, encoder_sigma: float | None = None,
                        encoder_latency: float = 0.0, check_encoders: bool = True,
                        systematic: bool | None = None) -> dict:
    """The options of a calibration that decide its result, in canonical form.

    :func:`options_hash` of them identifies "the same calibration of the same record".  Only the
    options that apply to the method are kept.

    Parameters
    ----------
    method : str
        The calibration method.
    states : str, optional
        The systematic filter's state set.
    settle, min_static : float
        The window segmentation's settling time and shortest static window [s].
    filter_rate_hz : float
        The systematic filter's rate [Hz].
    arw : float, optional
        Angle random walk [deg/sqrt(h)].
    vrw : float, optional
        Velocity random walk [ug/sqrt(Hz)].
    gravity : str, optional
        The gravity model given.
    encoder_sigma : float, optional
        The encoder noise [arcsec].
    encoder_latency : float
        The encoders' latency [s].
    check_encoders : bool
        Whether the encoder angles were checked against the increments.
    systematic : bool, optional
        The method reads the record itself, as systematic51/30 and unified do (default from the
        method's name).

    Returns
    -------
    dict
        The options (field units, as ``inscal calibrate`` takes them).

    Examples
    --------
    >>> from inscal import lab
    >>> lab.calibration_options("n25", settle=2.0)
    {'method': 'n25', 'settle_s': 2.0, 'min_static_s': 20.0, 'encoder_latency_s': 0.0, 'check_encoders': True}
    """
    if systematic is None:
        systematic = method in ("systematic51", "systematic30", "unified")
    opts: dict = {"method": method}
    if systematic:
        opts.update(states="auto" if states is None else str(states), filter_rate_hz=float(filter_rate_hz),
                    arw_deg_sqrt_h=arw, vrw_ug_sqrt_hz=vrw, encoder_sigma_arcsec=encoder_sigma)
    else:
        opts.update(settle_s=float(settle), min_static_s=float(min_static))
    opts.update(gravity=gravity, encoder_latency_s=float(encoder_latency), check_encoders=bool(check_encoders))
    return {k: v for k, v in opts.items() if v is not None}


def options_hash(options: dict) -> str:
    """``sha256:<hex>`` of the canonical JSON of ``options`` (sorted keys; floats by repr).

    Parameters
    ----------
    options : dict
        The options (:func:`calibration_options`).

    Returns
    -------
    str
        The :func:`text_hash` of their canonical JSON.

    Examples
    --------
    >>> from inscal import lab
    >>> lab.options_hash({"a": 1, "b": 2.0}) == lab.options_hash({"b": 2.0, "a": 1})
    True
    """
    return text_hash(json.dumps(to_jsonable(options), sort_keys=True, separators=(",", ":"), allow_nan=False))


def session_from_record(path, *, record_sha256: str | None = None, date=None, station: str | None = None,
                        operator: str | None = None, temperature_c: float | None = None, site=None) -> SessionInfo:
    """The session of a record file: its sha256, site, gravity model and path name from the file.

    Parameters
    ----------
    path : str or pathlib.Path
        The record.
    record_sha256 : str, optional
        Its hash (computed unless given).
    date : datetime.datetime or str, optional
        When it was taken (text: :func:`~inscal.lab.model.parse_date`); default: the record's
        ``created`` attribute (when the file was written).
    station, operator : str, optional
        Where and by whom.
    temperature_c : float, optional
        The IMU's temperature.
    site : Site, optional
        The site the calibration used instead of the record's (e.g. with another gravity model).

    Returns
    -------
    SessionInfo
        The session.

    Raises
    ------
    ValueError
        A record without a ``created`` time and no ``date``, or a date out of range.
    DataFileError
        A file that is not a readable record.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal import lab
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, file_hash, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> s = lab.session_from_record("still.h5", date="2025-01-31", station="bench-2")
    >>> s.record_sha256 == file_hash("still.h5"), round(s.latitude_deg, 3), s.date.year
    (True, 40.107, 2025)
    """
    info = record_info(path)
    if date is None:
        created = record_attrs(path, ("created",))["created"]
        if created is None:
            raise ValueError(f"{path} has no 'created' time: give the date of the run")
        date = created
    when = parse_date(date) if isinstance(date, str) else parse_date(date.isoformat())
    site = info.site if site is None else site
    gm = site.gravity_model.to_json()
    return SessionInfo(record_sha256=record_sha256 or file_hash(path), date=when, record_path=str(path),
                       station=station, operator=operator, latitude_deg=math.degrees(site.latitude),
                       longitude_deg=math.degrees(site.longitude), height_m=float(site.height),
                       gravity_model=json.dumps(gm, sort_keys=True), g_site_m_s2=float(site.gravity),
                       temperature_c=temperature_c,
                       path_name=(info.path.name if info.path is not None else None) or info.scenario or None)


def covariance_of(result) -> dict | None:
    """The covariance a :class:`~inscal.calibrate.CalibrationResult` reports, in the database's form.

    The systematic filter's full formal covariance of its parameter states (``result.covariance``:
    labels and ``P``, SI); a full parameter covariance ``diagnostics["covariance"]`` converted to field
    units; None when the method reports neither (the window-mean methods report 1 sigma only: the
    database then keeps the diagonal).

    Parameters
    ----------
    result : CalibrationResult
        The calibration.

    Returns
    -------
    dict or None
        ``{"basis", "labels", "units", "correlations", "matrix"}`` (see
        :class:`~inscal.lab.model.Calibration`), or None.

    Examples
    --------
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> res = CalibrationResult.from_field({"gyro_bias": [0.0] * 3}, {"gyro_bias": [0.0002] * 3}, "six-position")
    >>> lab.covariance_of(res) is None  # 1 sigma only
    True
    """
    cov = getattr(result, "covariance", None)
    basis = "states"
    if not (isinstance(cov, dict) and "P" in cov):
        cov = (getattr(result, "diagnostics", None) or {}).get("covariance")
        basis = "parameters"
    if not (isinstance(cov, dict) and "P" in cov and "labels" in cov):
        return None
    P = np.asarray(cov["P"], dtype=float)
    labels = [str(x) for x in cov["labels"]]
    if P.shape != (len(labels), len(labels)):
        return None
    if basis == "states":
        return {"basis": "states", "labels": labels, "units": "SI", "correlations": True,
                "matrix": to_jsonable(P)}
    labels = [parameter_label(lab) for lab in labels]
    scale = np.array([field_factor(lab) for lab in labels])
    return {"basis": "parameters", "labels": labels, "units": "field", "correlations": True,
            "matrix": to_jsonable(P * np.outer(scale, scale))}


def parameter_label(label: str) -> str:
    """The database's label ``name[component]`` (as :func:`parameter_rows` gives) of a parameter
    component written ``name[component]``, ``name.component`` (the table-free estimators' covariance
    labels) or ``name`` (a scalar); a label naming no registry parameter or component raises
    :class:`ParamFileError`."""
    if "[" in label:
        name, comp = label.split("[", 1)
        comp = comp.rstrip("]")
    elif "." in label:
        name, comp = label.split(".", 1)
    else:
        name, comp = label, ""
    if name not in PARAMETERS or comp not in parameter_components(name):
        raise ParamFileError(f"the covariance names {label!r}, not a component of a known parameter")
    return f"{name}[{comp}]" if comp else name


def field_factor(label: str) -> float:
    """The factor from SI to the field unit of a parameter component (``name[component]``,
    ``name.component`` or ``name``)."""
    name = parameter_label(label).split("[", 1)[0]
    kind, unit = PARAMETERS[name].kind, PARAMETERS[name].unit
    return float(units.from_si(1.0, unit, kind))


def parameter_covariance(rows: list[dict]) -> dict:
    """The diagonal covariance (field units) of parameter rows whose estimator reported 1 sigma only."""
    labels = [r["label"] for r in rows]
    var = [None if r["sigma"] is None else r["sigma"] ** 2 for r in rows]
    matrix = [[var[i] if i == j else 0.0 for j in range(len(rows))] for i in range(len(rows))]
    return {"basis": "parameters", "labels": labels, "units": "field", "correlations": False, "matrix": matrix}


def parse_param_text(text: str) -> dict:
    """The TOML document of a parameter file's text, checked for what the database needs (kind,
    schema version, method, known parameters of the right size).  Raises :class:`ParamFileError`."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParamFileError(f"not a valid TOML file ({exc})") from None
    if doc.get("kind") != KIND:
        raise ParamFileError(f"not an inscal parameter file (kind = {doc.get('kind')!r})")
    ver = doc.get("schema_version")
    if not isinstance(ver, int) or not 1 <= ver <= PARAM_SCHEMA_VERSION:
        raise ParamFileError(f"parameter file schema_version {ver!r} is not one this inscal reads")
    if not isinstance(doc.get("method"), str):
        raise ParamFileError("the parameter file has no 'method'")
    params = doc.get("parameters")
    if not isinstance(params, dict) or not params:
        raise ParamFileError("the parameter file has no [parameters] section")
    for name, entry in params.items():
        if name not in PARAMETERS:
            raise ParamFileError(f"unknown parameter {name!r}")
        if not isinstance(entry, dict) or "value" not in entry or "unit" not in entry:
            raise ParamFileError(f"parameter {name} needs 'value' and 'unit'")
    try:
        errors_from_field({n: {"value": np.squeeze(np.asarray(e["value"], dtype=float)).tolist(), "unit": e["unit"]}
                           for n, e in params.items()})
    except (ValueError, TypeError, KeyError) as exc:
        raise ParamFileError(str(exc)) from None
    return doc


def _flat(v, n: int) -> list[float | None]:
    a = np.ravel(np.asarray(v if v is not None else [np.nan] * n, dtype=float))
    if a.size == 1 and n > 1:
        a = np.full(n, a[0])
    if a.size != n:
        raise ParamFileError(f"expected {n} numbers, got {a.size}")
    return [float(x) if math.isfinite(x) else None for x in a]


def parameter_rows(doc: dict) -> list[dict]:
    """One row per parameter component (name, component, label, value, sigma, sigma_formal, unit) of a
    parameter file's document, in the field units of :data:`~inscal.core.error_model.PARAMETERS` (a
    file in other units is converted here, the one place the database converts units); None where
    not a finite number."""
    rows = []
    for name, entry in doc["parameters"].items():
        comps = parameter_components(name)
        n = len(comps)
        kind, unit = PARAMETERS[name].kind, PARAMETERS[name].unit
        given = str(entry["unit"])

        def field(v, name=name, given=given, kind=kind, unit=unit):  # a file in other units (typed in by hand): converted
            if v is None or given == unit:
                return v
            try:
                return units.from_si(np.asarray(units.to_si(np.asarray(v, dtype=float), given, kind)), unit).tolist()
            except (units.UnitError, ValueError, TypeError) as exc:
                raise ParamFileError(f"parameter {name}: {exc}") from None

        vals = _flat(field(entry["value"]), n)
        sig = _flat(field(entry.get("sigma")), n)
        formal = _flat(field(entry["sigma_formal"]), n) if "sigma_formal" in entry else [None] * n
        for k, comp in enumerate(comps):
            rows.append({"name": name, "component": k, "label": f"{name}[{comp}]" if comp else name,
                         "value": vals[k], "sigma": sig[k], "sigma_formal": formal[k], "unit": unit})
    return rows


def fit_of(doc: dict) -> tuple[dict | None, float | None, float | None, float | None]:
    """``(fit table, chi2, dof, p)`` of a parameter file: its ``[fit]`` (the window-mean methods), or the
    innovation statistics of the systematic filter (``[metadata]`` chi2, dof, p_value, nis_mean)."""
    fit = doc.get("fit")
    if not isinstance(fit, dict):
        meta = doc.get("metadata") or {}
        fit = {k: meta[k] for k in ("chi2", "dof", "p_value", "nis_mean") if k in meta} or None
    if fit is None:
        return None, None, None, None

    def num(key):
        v = fit.get(key)
        return float(v) if isinstance(v, (int, float)) and math.isfinite(float(v)) else None

    return to_jsonable(fit), num("chi2"), num("dof"), num("p_value")
