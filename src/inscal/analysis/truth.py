"""Errors of a calibration against the truth of a simulated record, per parameter and per S16 Table 2
group, and the normalised errors (NEES) of a systematic result."""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate import RECORD_METHODS
from inscal.calibrate.systematic.params import CompParams, truth_in_frame
from inscal.core import units
from inscal.core.error_model import (
    PARAMETERS,
    GimbalErrors,
    ImuErrors,
    parameter_components,
)


def parameter_errors(imu: ImuErrors, gimbal: GimbalErrors | None, true_imu: ImuErrors, true_gimbal: GimbalErrors,
                     names) -> dict[str, float]:
    """``{"accel_bias.z": estimate - truth, ...}`` in field units for the registry
    parameters ``names``."""
    out = {}
    for name in names:
        p = PARAMETERS[name]
        attr, unit = p.attribute, p.unit
        est_src, true_src = (imu, true_imu) if p.group == "imu" else (gimbal, true_gimbal)
        if est_src is None:
            continue
        err = units.from_si(np.asarray(getattr(est_src, attr), float) - np.asarray(getattr(true_src, attr), float), unit)
        for comp, v in zip(parameter_components(name), np.ravel(err)):
            out[f"{name}.{comp}" if comp else name] = float(v)
    return out


def estimated_parameter_names(result) -> list[str]:
    """The names of :data:`~inscal.core.error_model.PARAMETERS` that ``result`` estimates (all of them when it does not say)."""
    est = getattr(result, "estimated", None)
    names = [n for n in (est or PARAMETERS) if n in PARAMETERS]
    return names


def is_record_method(method: str) -> bool:
    """Methods that read the increments (the systematic filter), not window means."""

    return method in RECORD_METHODS


def result_errors(res, true_imu: ImuErrors, true_gimbal: GimbalErrors) -> tuple[dict[str, float], dict[str, float]]:
    """``({"accel_bias.z": estimate - truth, ...}, {same keys: 1 sigma})`` in field units for
    every component that ``res`` estimates.

    A method that defines its own IMU frame (``res.truth_transform`` set: the systematic
    filter, gyro-defined S16 m-frame) is compared with the truth mapped into that frame, and
    the components fixed by the frame definition or the model (NaN sigma: the three upper gyro
    angles of the gyro-defined frame, the off-diagonal lever arms of the S16 form) are left
    out: they are not estimates, so their (zero) error says nothing.  Parameters a method does
    not estimate (the gimbal, for the systematic filter) are absent, never zero errors.
    Sigmas are returned where the result has them (NaN placeholders are dropped)."""
    transform = res.truth_transform
    ti, tg = transform((true_imu, true_gimbal)) if transform is not None else (true_imu, true_gimbal)
    names = estimated_parameter_names(res)
    err = parameter_errors(res.imu, res.gimbal, ti, tg, names)
    sig: dict[str, float] = {}
    sigma = getattr(res, "sigma", None) or {}
    for name in names:
        if name not in sigma:
            continue
        v = np.ravel(units.from_si(np.asarray(sigma[name], float), PARAMETERS[name].unit))
        comps = parameter_components(name)
        if v.size != len(comps):
            continue
        for comp, x in zip(comps, v):
            sig[f"{name}.{comp}" if comp else name] = float(x)
    if transform is not None:
        err = {k: v for k, v in err.items() if math.isfinite(sig.get(k, math.nan))}
    return err, {k: sig[k] for k in err if k in sig and math.isfinite(sig[k])}


def systematic_statistics(res, true_imu: ImuErrors, true_gimbal: GimbalErrors | None = None) -> dict:
    """Per-run statistics of a systematic calibration against the truth: ``errors`` and
    ``sigmas`` per estimated component (field units, truth mapped into the filter's frame,
    components fixed by the frame or the model left out), and the NEES of the parameter error
    state (``e`` = :meth:`CompParams.error_state` of the estimate against
    :func:`truth_in_frame`, ``P`` = ``res.covariance["P"]``, ``dof`` = len(e)) with the
    per-state ``z = e / sqrt(diag P)``.  State sets with the gimbal states (``unified``): the
    estimate's ``res.gimbal`` against ``true_gimbal`` (default ideal) enter ``e``, so the NEES
    counts ``dth`` and the mount attitude too."""

    tg = GimbalErrors() if true_gimbal is None else true_gimbal
    err, sig = result_errors(res, true_imu, tg)
    st = res.states
    est = CompParams.from_imu(res.imu)
    if st.gimbal:
        est.gim = np.concatenate([[res.gimbal.nonorthogonality], np.asarray(res.gimbal.mount_attitude, float)])
    e = est.error_state(st, truth_in_frame(true_imu, st, tg if st.gimbal else None))
    P = np.asarray(res.covariance["P"], float)
    d = np.sqrt(np.diag(P))
    z = e / d
    nees = float(z @ np.linalg.solve(P / np.outer(d, d), z))  # correlation form: well conditioned
    inn = res.diagnostics["innovations"]
    return {"errors": err, "sigmas": sig, "nees": nees, "dof": int(e.size), "z": z.tolist(),
            "states": res.diagnostics["state_options"],
            "nis_mean": float(inn["nis_mean"]), "passes": len(res.diagnostics["passes"]),
            "converged": bool(res.diagnostics["converged"])}
