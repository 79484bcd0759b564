"""The thermal states of the systematic filter (option ``thermal``; the model in
:mod:`inscal.calibrate.systematic.states`): the temperature of every sample from the record's readings, and
the canonical thermal model with its 1 sigma from the filter's estimate and covariance.

Calibration in one run (beyond both papers): a continuous rotation sequence while the chamber ramps
calibrates the base errors at ``T_ref`` and every thermal coefficient together, the measured temperature
entering each sample's compensation as a known input.  What separates a coefficient from the base term and
from the other orders is the temperature history: a constant temperature leaves each coefficient in one
combination with the base bias or scale factor (only ``b + c_1 dT + c_2 dT^2 ...`` at that dT is seen); a
ramp at a constant rate leaves the dT/dt term in one combination with the base gyro bias (``b + D dT/dt``);
the holds before and after a ramp, where dT/dt steps, separate it (``inscal observability`` reports how
well a profile does).
"""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate.systematic.params import CompParams, thermal_from_rows
from inscal.calibrate.systematic.states import (
    K_TH,
    TH_RATE_ROW,
    THERMAL_ROWS,
    THERMAL_TERM_NAMES,
    StateSet,
    field_value,
    thermal_group_order,
    thermal_group_term,
)
from inscal.calibrate.windows import CalibrationError
from inscal.core.error_model import ImuErrors
from inscal.core.thermal import (
    RATE_WINDOW_S,
    ThermalError,
    ThermalModel,
    sample_temperature,
    select_sensor,
    temperature_rate,
)

#: default reference temperature of the thermal states [degC] (that of the plateau method)
T_REF_C = 20.0


def sample_inputs(rec, n: int, rate_hz: float, t_ref: float, sensor: str = "",
                  rate_window_s: float = RATE_WINDOW_S) -> dict:
    """The temperature of each of the ``n`` samples of record ``rec`` from its ``temperature`` readings
    (:func:`inscal.core.thermal.sample_temperature`: the reading at the middle of each sample interval, dT/dt
    the least-squares slope over ``rate_window_s``): ``{"dT": T - t_ref, "rate": dT/dt, "t_min", "t_max",
    "span", "rate_max", "sensor"}``.  One-line CalibrationError without readings or with unusable ones."""
    temp = getattr(rec, "temperature", None)
    if temp is None:
        raise CalibrationError("the thermal states need the record's temperature (/temperature): this record has none")
    if not (isinstance(t_ref, (int, float)) and math.isfinite(t_ref)):
        raise CalibrationError(f"t_ref must be a temperature in degC, got {t_ref!r}")
    if not (isinstance(rate_window_s, (int, float)) and math.isfinite(rate_window_s) and rate_window_s > 0):
        raise CalibrationError(f"the temperature-rate window must be > 0 s, got {rate_window_s!r}")
    time = getattr(rec, "time", None)
    ts = np.asarray(time, float) if time is not None else (np.arange(n) + 1.0) / rate_hz
    if ts.shape != (n,):
        raise CalibrationError(f"record time has shape {ts.shape}, the increments {n} samples")
    try:
        tt = np.asarray(temp.time, float)
        T = select_sensor(temp.values, temp.sensors, sensor)
        rate = temperature_rate(tt, T, rate_window_s)
        Ts, rs = sample_temperature(ts, rate_hz, tt, T, rate, where="record")
    except ThermalError as exc:
        raise CalibrationError(str(exc)) from None
    t_min, t_max = float(np.min(Ts)), float(np.max(Ts))
    if not t_min <= t_ref <= t_max:
        side, edge = ("below", t_min) if t_ref < t_min else ("above", t_max)
        raise CalibrationError(f"t_ref {t_ref:.6g} degC lies {side} the record's temperatures ({t_min:.6g} .. "
                               f"{t_max:.6g} degC, by {abs(t_ref - edge):.3g} degC): the thermal model would be "
                               "extrapolated to its reference; give a --t-ref within them")
    dT = Ts - float(t_ref)
    return {"dT": dT, "rate": rs, "t_min": t_min, "t_max": t_max, "span": float(np.max(np.abs(dT))),
            "rate_max": float(np.max(np.abs(rs))), "sensor": sensor, "t_ref": float(t_ref),
            "rate_window_s": float(rate_window_s)}


def thermal_result(est: CompParams, st: StateSet, P_post: np.ndarray, prior: np.ndarray, scale: float,
                   imu: ImuErrors, info: dict, P_all: np.ndarray | None = None,
                   prior_all: np.ndarray | None = None) -> tuple[ThermalModel, dict, dict, list[str]]:
    """The canonical thermal model of the estimate ``est`` (with the base errors ``imu`` at ``t_ref``), the 1 sigma
    of every coefficient (``P_post`` the parameter covariance of the states, SI; times the innovation fit's
    ``scale``, as the base parameters' sigma), a table per coefficient group (value, sigma, prior, ratio in field
    units: the canonical coefficients, those of the model) and the notes: coefficients the record leaves at their
    prior (posterior >= 0.5 prior sigma).  ``P_post`` and ``prior`` hold the thermal states alone (the last groups
    of ``st``).  With ``P_all`` and ``prior_all`` (every parameter state) the table also gives each coefficient's
    ``data_sigma_ratio`` (:func:`data_information`) and the notes name the coefficients the data alone do not
    separate from the other parameters (``data_sigma_ratio`` above 0.5): a ramp at one rate leaves the dT/dt term
    in one combination with the base gyro bias, whose prior then decides both."""
    orders = st.thermal
    model = thermal_from_rows(est.th, orders, imu, info["t_ref"], info["t_min"], info["t_max"], info["sensor"])
    post = np.sqrt(np.maximum(np.diag(P_post), 0.0))
    sig_rows = np.full(est.th.shape, np.nan)
    dinfo = None
    if P_all is not None and prior_all is not None:
        first = np.asarray(prior_all).shape[0] - np.asarray(prior).shape[0]
        dinfo = data_information(P_all, prior_all, first)
    k = 0
    table, weak = {}, []
    for g in st.groups:
        if g.kinds[0] != K_TH:
            continue
        rows, axes = list(g.js), list(g.axes)
        sig_rows[rows, axes] = post[k:k + g.size]
        ratio = post[k:k + g.size] / prior[k:k + g.size]
        # the canonical coefficient: a scale-factor state is c_K / (1 + K_0) (states module docstring)
        term = thermal_group_term(g)
        canon = 1.0 + np.asarray(getattr(imu, term), float)[axes] if term.endswith("scale_factor") else 1.0
        table[g.name] = {"unit": g.unit, "value": field_value(est.th[rows, axes] * canon, g.unit).tolist(),
                         "sigma": field_value(scale * post[k:k + g.size] * canon, g.unit).tolist(),
                         "prior_sigma": field_value(prior[k:k + g.size] * canon, g.unit).tolist(),
                         "ratio": ratio.tolist()}
        bad = ratio >= 0.5
        if dinfo is not None:
            dratio = 1.0 / np.sqrt(np.maximum(dinfo[k:k + g.size], 1e-300))
            table[g.name]["data_sigma_ratio"] = np.minimum(dratio, 1e300).tolist()
            bad = bad | (dratio > 0.5)
        if np.any(bad):
            weak.append(f"{g.name} {''.join(a for a, b in zip('xyz', bad) if b)}")
        k += g.size
    sigma = {}
    for term, o in zip(THERMAL_TERM_NAMES, orders):
        if term == "gyro_bias_rate":
            if o:
                sigma[term] = scale * sig_rows[TH_RATE_ROW]
            continue
        row = THERMAL_ROWS[term][0]
        s = scale * sig_rows[row:row + o]
        if term.endswith("scale_factor"):
            s = s * (1.0 + np.asarray(getattr(imu, term), float))[None, :]
        sigma[term] = s
    notes = []
    if weak:
        what = ("posterior sigma >= 0.5 x prior, or the data alone, every other parameter free, leave more than 0.5 x "
                "prior" if dinfo is not None else "posterior sigma >= 0.5 x prior")
        notes.append(f"thermal coefficients not observed by this temperature history ({what}): "
                     + "; ".join(weak) + " (a constant temperature leaves every coefficient in one combination with "
                     "the base term; a ramp without holds leaves the dT/dt term with the gyro bias: inscal observability)")
    return model, sigma, table, notes


#: a direction of the other parameters with less information from the data than this (in units of its prior's)
#: counts as free in :func:`data_information` (a noise-free record's covariance spans ~1e12 of it: its
#: round-off there is ~1e-4)
FREE_INFO = 1e-3


def data_information(P_post: np.ndarray, prior: np.ndarray, first: int) -> np.ndarray:
    """The information of the data alone about each parameter state from index ``first`` on (the thermal ones), in
    units of its prior's (1 / (data-only sigma / prior sigma)^2), with every other parameter free: ``P_post`` the
    posterior covariance of all parameter states and ``prior`` their prior 1 sigma (SI).  The data's information
    ``L = P_post^-1 - diag(prior^-2)`` (scaled by the prior), then for each state its Schur complement against all
    the others (directions of the others with less than :data:`FREE_INFO` left free).  Zero when the data see
    the coefficient only in one combination with other parameters (a base term, another order)."""
    s = np.asarray(prior, float)
    Ps = np.asarray(P_post, float) / np.outer(s, s)
    w, V = np.linalg.eigh(0.5 * (Ps + Ps.T))
    L = (V / np.maximum(w, 1e-300)) @ V.T - np.eye(s.shape[0])
    L = 0.5 * (L + L.T)
    n = s.shape[0]
    out = np.empty(n - first)
    for i in range(first, n):
        rest = np.r_[0:i, i + 1:n]
        wr, Vr = np.linalg.eigh(L[np.ix_(rest, rest)])
        keep = wr > FREE_INFO
        a = Vr[:, keep].T @ L[rest, i]
        out[i - first] = max(float(L[i, i] - np.sum(a * a / wr[keep])), 0.0)
    return out


def thermal_labels(st: StateSet) -> list[tuple[str, str, int]]:
    """``(group, term, order)`` of every thermal group of ``st`` (order 0: the dT/dt term)."""
    return [(g.name, thermal_group_term(g), thermal_group_order(g)) for g in st.groups if g.kinds[0] == K_TH]


def thermal_offset(st: StateSet) -> int:
    """Index of the first thermal state among the parameter states (``st.n_params`` without any)."""
    k = 0
    for g in st.groups:
        if g.kinds[0] == K_TH:
            return k
        k += g.size
    return k

