"""Temperature in the reports: a record's temperature and its rate of change, and each thermal
parameter's curve over the calibrated range with its 1-sigma band (:mod:`inscal.core.thermal`).

The curve of a term (a bias, a scale factor or a misalignment, every component a line) is its value
at ``dT/dt = 0``::

    p(T) = p_0 + sum_k c_k (T - T_ref)^k                  p_0: the parameter at T_ref

drawn solid over the calibrated range ``t_min .. t_max`` and dashed where the plot extends beyond
it.  Its band is +-1 sigma propagated from the 1-sigma of ``p_0`` and of each coefficient::

    sigma_p(T)^2 = sigma_0^2 + sum_k (sigma_k (T - T_ref)^k)^2      (no covariance: correlations left out)
    sigma_p(T)^2 = J C J^T,   J = [1, dT, .., dT^n]                  (with a covariance C of [p_0, c_1 .. c_n])

The gyro bias term in dT/dt (:data:`~inscal.core.thermal.RATE_TERM`) is a number with its sigma.

Per-plateau estimates (a plateau calibration: one estimate per chamber plateau) are drawn as
error bars over the curves.  Their shape (:class:`PlateauPoint`, or a plain dict with the same
keys, as a calibration's ``diagnostics["plateaus"]`` holds them)::

    {"temperature_c": 35.0,                                  the plateau's mean temperature [degC]
     "values": {"gyro_bias": array (3,), ...},               the estimates at that temperature (SI,
     "sigma":  {"gyro_bias": array (3,), ...}}               names of THERMAL_TERMS) and their 1 sigma

Everything is computed in SI and converted to the field units of
:data:`~inscal.core.thermal.THERMAL_TERMS` (ppm, deg/h, ug, arcsec) for the plots and the numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from inscal.core import units
from inscal.core.error_model import ImuErrors, parameter_components
from inscal.core.thermal import (
    RATE_TERM,
    RATE_WINDOW_S,
    THERMAL_TERMS,
    ThermalModel,
    temperature_rate,
)
from inscal.report.figures import new_figure, png_base64, time_axis
from inscal.report.html import display_unit, escape, fmt_num, html_table

#: seconds per minute: temperature rates are shown in degC/min
PER_MINUTE = units.to_si(1.0, "min")
#: temperatures on a curve
CURVE_POINTS = 101
#: the plot extends this fraction of the calibrated range beyond each end (drawn dashed)
EXTEND = 0.1
#: readings of each temperature series kept for the plot and the JSON (the rate is computed on all)
SERIES_POINTS = 2000
#: readable names of the thermal terms
TERM_TITLES = {
    "gyro_bias": "Gyro bias", "gyro_scale_factor": "Gyro scale factor", "gyro_misalignment": "Gyro misalignment",
    "accel_bias": "Accelerometer bias", "accel_scale_factor": "Accelerometer scale factor",
    "accel_misalignment": "Accelerometer misalignment", RATE_TERM[0]: "Gyro bias per dT/dt",
}
#: display spelling of the dT/dt term's unit
RATE_DISPLAY = RATE_TERM[2].replace("deg/h", "°/h").replace("degC", "°C")
STYLE = (".thermal-figs{display:flex;flex-wrap:wrap;gap:8px}.thermal-figs figure{margin:0;flex:1 1 520px;max-width:540px}"
         ".thermal-figs img{max-width:100%}figcaption{font-size:12px;color:#444}p.thermal{font-size:14px}")


class PlateauError(ValueError):
    """Per-plateau estimates that cannot be drawn, with the reason (one line)."""


@dataclass(frozen=True)
class PlateauPoint:
    """One plateau's estimates: the temperature [degC], the estimated values and their 1 sigma (SI,
    keyed by the names of :data:`~inscal.core.thermal.THERMAL_TERMS`; a name may be missing)."""

    temperature_c: float
    values: dict[str, np.ndarray] = field(default_factory=dict)
    sigma: dict[str, np.ndarray] = field(default_factory=dict)


def plateau_points(items) -> list[PlateauPoint]:
    """:class:`PlateauPoint` s from a list of them or of dicts ``{"temperature_c", "values", "sigma"}``
    (the module docstring); :class:`PlateauError` names the first malformed entry."""
    out = []
    for i, p in enumerate(items or []):
        if isinstance(p, PlateauPoint):
            p = {"temperature_c": p.temperature_c, "values": p.values, "sigma": p.sigma}
        if not isinstance(p, dict):
            raise PlateauError(f"plateau {i}: expected a dict with temperature_c, values and sigma, got {type(p).__name__}")
        try:
            t = float(p["temperature_c"])
        except (KeyError, TypeError, ValueError):
            raise PlateauError(f"plateau {i}: temperature_c missing or not a number of degC") from None
        if not math.isfinite(t):
            raise PlateauError(f"plateau {i}: temperature_c is {t}")
        vals, sig = {}, {}
        for key, dest in (("values", vals), ("sigma", sig)):
            d = p.get(key) or {}
            if not isinstance(d, dict):
                raise PlateauError(f"plateau {i}: {key} must map parameter names to arrays")
            for name, v in d.items():
                if name not in THERMAL_TERMS:
                    continue  # a parameter that does not follow the temperature: not drawn
                size = THERMAL_TERMS[name][3]
                try:
                    a = np.asarray(v, dtype=float).reshape(size)
                except (TypeError, ValueError):
                    raise PlateauError(f"plateau {i}: {key}.{name} is not {size} numbers") from None
                dest[name] = a
        out.append(PlateauPoint(t, vals, sig))
    return out


# ------------------------------------------------------------------------------ the record's temperature
def temperature_data(temp, window_s: float = RATE_WINDOW_S, max_points: int = SERIES_POINTS) -> dict:
    """The numbers behind the temperature plot of a record's readings (:class:`inscal.io.records.Temperature`):
    per sensor its range and largest ``|dT/dt|`` (the least-squares slope over ``window_s``,
    :func:`~inscal.core.thermal.temperature_rate`, on every reading), the series thinned to at most
    ``max_points`` readings, and a one-line summary."""
    t = np.asarray(temp.time, dtype=float)
    step = max(1, -(-t.size // max_points))
    sensors, series_t, series_r = {}, {}, {}
    for k, name in enumerate(temp.sensors):
        y = np.asarray(temp.values[:, k], dtype=float)
        rate = temperature_rate(t, y, window_s) * PER_MINUTE
        sensors[name] = {"min_c": float(y.min()), "max_c": float(y.max()),
                         "max_abs_rate_c_per_min": float(np.max(np.abs(rate)))}
        series_t[name] = y[::step].tolist()
        series_r[name] = rate[::step].tolist()
    lo = min(s["min_c"] for s in sensors.values())
    hi = max(s["max_c"] for s in sensors.values())
    rmax = max(s["max_abs_rate_c_per_min"] for s in sensors.values())
    names = ", ".join(temp.sensors)
    line = (f"{len(sensors)} sensor{'s' if len(sensors) > 1 else ''} ({names}), {t.size} readings over "
            f"{t[-1] - t[0]:.6g} s: {lo:.2f} .. {hi:.2f} degC, max |dT/dt| {rmax:.3g} degC/min "
            f"(least-squares slope over {window_s:g} s)")
    return {"sensors": sensors, "range_c": [lo, hi], "max_abs_rate_c_per_min": rmax, "rate_window_s": window_s,
            "summary": line, "series": {"time_s": t[::step].tolist(), "temperature_c": series_t,
                                        "rate_c_per_min": series_r}}


def temperature_figure(data: dict):
    """The temperature of each sensor over time and its rate dT/dt (two panels); the caller closes it."""
    plt = new_figure()
    s = data["series"]
    t, tlabel = time_axis(np.asarray(s["time_s"]))
    fig, ax = plt.subplots(2, 1, figsize=(10, 4.8), sharex=True)
    for name in s["temperature_c"]:
        ax[0].plot(t, s["temperature_c"][name], lw=1.0, label=name)
        ax[1].plot(t, s["rate_c_per_min"][name], lw=0.9, label=name)
    ax[0].set(ylabel="temperature [°C]", title="Temperature")
    ax[1].set(xlabel=tlabel, ylabel="dT/dt [°C/min]")
    ax[1].axhline(0.0, color="k", lw=0.5)
    for a in ax:
        a.grid(alpha=0.3)
        a.legend(loc="best", fontsize=8)
    fig.subplots_adjust(left=0.08, right=0.98, top=0.93, bottom=0.1, hspace=0.08)
    return fig


def temperature_section(temp, window_s: float = RATE_WINDOW_S) -> tuple[str, dict]:
    """HTML of the record's temperature (figure and one-line summary) and its numbers."""
    data = temperature_data(temp, window_s)
    plt = new_figure()
    fig = temperature_figure(data)
    try:
        b64 = png_base64(fig)
    finally:
        plt.close(fig)
    html = (f"<h2>Temperature</h2><p class='thermal'>{escape(data['summary'])}</p>"
            f"<img alt='temperature' src='data:image/png;base64,{b64}'/>")
    return html, data


# ------------------------------------------------------------------------------ the thermal model's curves
def fit_of(thermal_fit: dict | None, name: str) -> dict | None:
    """The fit statistics of one term (``chi2``, ``dof``, ``p_value`` ..., scalars or one per component)
    from a thermal fit dict keyed by term (``fit[name]`` or ``fit["terms"][name]``); None when absent."""
    if not isinstance(thermal_fit, dict):
        return None
    terms = thermal_fit.get("terms")
    entry = terms.get(name) if isinstance(terms, dict) else None
    if entry is None:
        entry = thermal_fit.get(name)
    if not isinstance(entry, dict):
        return None
    keep = {k: entry[k] for k in ("chi2", "dof", "p_value", "consistent", "scale", "note") if k in entry}
    if "p_value" not in keep and "p" in entry:
        keep["p_value"] = entry["p"]
    return keep or None


def fit_text(fit: dict | None, components=()) -> str:
    """``χ²/dof = 3.1/4, p = 0.54``, or one such text per component (``x: ...; y: ...``) when the fit has
    one value per component."""
    if not fit:
        return ""
    try:
        chi2, dof, p = (np.atleast_1d(np.asarray(fit.get(k, np.nan), dtype=float)).ravel()
                        for k in ("chi2", "dof", "p_value"))
    except (TypeError, ValueError):
        return ""
    n = max(chi2.size, dof.size, p.size)
    parts = []
    for i in range(n):
        c, d, q = (a[min(i, a.size - 1)] for a in (chi2, dof, p))
        name = f"{components[i]}: " if n > 1 and i < len(components) and components[i] else ""
        parts.append(f"{name}χ²/dof = {fmt_num(c, 3)}/{fmt_num(d, 3)}, p = {fmt_num(q, 3)}")
    return "; ".join(parts)


def _plot_span(model: ThermalModel, points: list[PlateauPoint], span) -> tuple[float, float]:
    """The temperatures a curve is drawn over: the calibrated range (the plateaus, the record's span and
    T_ref +- 20 degC where the range is open) extended by :data:`EXTEND` of it on each side."""
    extra = [p.temperature_c for p in points] + ([float(x) for x in span] if span is not None else [])
    lo = model.t_min if math.isfinite(model.t_min) else min([model.t_ref - 20.0, *extra])
    hi = model.t_max if math.isfinite(model.t_max) else max([model.t_ref + 20.0, *extra])
    pad = EXTEND * max(hi - lo, 1.0)
    return min([lo - pad, *extra]), max([hi + pad, *extra])


def term_curve(model: ThermalModel, sigma: dict, base: ImuErrors, base_sigma: dict, name: str, temps: np.ndarray,
               covariance=None) -> tuple[np.ndarray, np.ndarray | None]:
    """Value (n, size) and 1 sigma (n, size, None without any sigma) of term ``name`` at ``temps`` (SI).
    ``covariance``: (size, order+1, order+1) over [p_0, c_1 .. c_order] per component, or None (then the
    sigmas are combined as independent)."""
    attr = THERMAL_TERMS[name][0]
    dT = np.asarray(temps, dtype=float) - model.t_ref
    value = np.asarray(getattr(base, attr), dtype=float) + model.delta(name, dT)
    order = model.order(name)
    powers = dT[:, None] ** np.arange(order + 1)[None, :]  # J = [1, dT, .., dT^order]
    if covariance is not None:
        C = np.asarray(covariance, dtype=float)
        size = THERMAL_TERMS[name][3]
        if C.shape != (size, order + 1, order + 1):
            raise ValueError(f"thermal {name}: covariance has shape {C.shape}, expected ({size}, {order + 1}, {order + 1})")
        var = np.einsum("nk,ikl,nl->ni", powers, C, powers)
        return value, np.sqrt(np.maximum(var, 0.0))
    s0 = base_sigma.get(name)
    sk = sigma.get(name)
    if s0 is None and sk is None:
        return value, None
    size = value.shape[1]
    s0 = np.zeros(size) if s0 is None else np.nan_to_num(np.asarray(s0, dtype=float).reshape(size))
    sk = np.zeros((order, size)) if sk is None else np.nan_to_num(np.asarray(sk, dtype=float).reshape(order, size))
    var = s0[None, :] ** 2 + ((powers[:, 1:, None] * sk[None, :, :]) ** 2).sum(axis=1)
    return value, np.sqrt(var)


def thermal_data(model: ThermalModel, sigma: dict | None, base: ImuErrors, base_sigma: dict | None = None,
                 fit: dict | None = None, plateaus=None, truth: tuple[ImuErrors, ThermalModel] | None = None,
                 covariance: dict | None = None, span=None, n: int = CURVE_POINTS) -> dict:
    """The numbers behind the thermal figures, in field units: for each term that follows the temperature
    its curve (``temperature_c`` (n,), ``value`` (n, size), ``sigma`` (n, size) or None, ``in_range`` (n,)),
    the coefficients with their sigmas, the per-plateau points, the fit and, with ``truth``
    ``(ImuErrors at T_ref, ThermalModel)``, the true curve; the dT/dt term; a caption per figure.

    ``sigma``: 1 sigma of the coefficients (SI, the model's array shapes); ``base_sigma``: of the
    parameters at T_ref (SI, names of PARAMETERS); ``covariance``: ``{name: (size, order+1, order+1)}``
    over [p_0, c_1 ..] per component (SI), else the band leaves the correlations out; ``span``: the
    record's temperature range (drawn shaded); ``plateaus``: see :func:`plateau_points`."""
    sigma, base_sigma, covariance = sigma or {}, base_sigma or {}, covariance or {}
    points = plateau_points(plateaus)
    a, b = _plot_span(model, points, span)
    marks = [x for x in (model.t_min, model.t_ref, model.t_max) if math.isfinite(x) and a <= x <= b]
    temps = np.unique(np.concatenate([np.linspace(a, b, n), marks]))
    in_range = (temps >= model.t_min) & (temps <= model.t_max)
    rng = f"{model.t_min:g} .. {model.t_max:g} °C"
    terms = {}
    for name, (attr, _kind, unit, size, _mx) in THERMAL_TERMS.items():
        order = model.order(name)
        if order == 0:
            continue
        value, sig = term_curve(model, sigma, base, base_sigma, name, temps, covariance.get(name))

        def conv(v, unit=unit):
            return units.from_si(np.asarray(v, dtype=float), unit)

        coefs = []
        for k in range(order):
            fu = units.per_degree_unit(unit, k + 1)
            s = sigma.get(name)
            coefs.append({"order": k + 1, "unit": fu, "value": conv(getattr(model, name)[k]).tolist(),
                          "sigma": conv(np.asarray(s, dtype=float).reshape(order, size)[k]).tolist() if s is not None else None})
        s0 = base_sigma.get(name)
        entry = {
            "title": TERM_TITLES[name], "unit": unit, "order": order, "t_ref": model.t_ref, "components": parameter_components(name),
            "temperature_c": temps.tolist(), "in_range": in_range.tolist(),
            "value": conv(value).tolist(), "sigma": conv(sig).tolist() if sig is not None else None,
            "base": {"value": conv(getattr(base, attr)).tolist(),
                     "sigma": conv(np.asarray(s0, dtype=float).reshape(size)).tolist() if s0 is not None else None},
            "coefficients": coefs, "correlations": name in covariance, "fit": fit_of(fit, name),
            "plateaus": [{"temperature_c": p.temperature_c, "value": conv(p.values[name]).tolist(),
                          "sigma": conv(p.sigma[name]).tolist() if name in p.sigma else None}
                         for p in points if name in p.values],
        }
        if truth is not None:
            ti, tm = truth
            entry["truth"] = conv(np.asarray(getattr(ti, attr), dtype=float)
                                  + tm.delta(name, temps - tm.t_ref)).tolist()
        given = [w for w, ok in (("the coefficients'", name in sigma), ("the T_ref value's", s0 is not None)) if ok]
        band = ("no 1σ given: no band" if sig is None else
                "band ±1σ from the covariance of the T_ref value and the coefficients" if name in covariance else
                f"band ±1σ propagated from {' and '.join(given)} 1σ, correlations not included (no covariance)")
        entry["caption"] = (f"{TERM_TITLES[name]} [{display_unit(unit)}] at dT/dt = 0: value at T_ref "
                            f"{model.t_ref:g} °C + polynomial of order {order} in T − T_ref; calibrated range {rng} solid"
                            + (", beyond it dashed" if not in_range.all() else "") + f"; {band}."
                            + (" Points: per-plateau estimates ±1σ." if entry["plateaus"] else "")
                            + (" Dotted: the simulation's truth." if truth is not None else "")
                            + (f" Fit: {fit_text(entry['fit'], entry['components'])}." if entry["fit"] else ""))
        terms[name] = entry
    out = {"t_ref": model.t_ref, "t_min": model.t_min, "t_max": model.t_max, "out_of_range": model.out_of_range,
           "sensor": model.sensor, "terms": terms,
           "constant": [name for name in THERMAL_TERMS if model.order(name) == 0],
           "record_span_c": [float(x) for x in span] if span is not None else None}
    if model.has_rate or RATE_TERM[0] in sigma:
        s = sigma.get(RATE_TERM[0])
        rate = {"unit": RATE_TERM[2], "value": units.from_si(model.gyro_bias_rate, RATE_TERM[2]).tolist(),
                "sigma": units.from_si(np.asarray(s, dtype=float).reshape(3), RATE_TERM[2]).tolist() if s is not None else None,
                "fit": fit_of(fit, RATE_TERM[0])}
        if truth is not None:
            rate["truth"] = units.from_si(truth[1].gyro_bias_rate, RATE_TERM[2]).tolist()
        out["rate"] = rate
    return out


def thermal_figure(term: dict, span=None):
    """The figure of one term of :func:`thermal_data`: every component a line with its ±1σ band, solid
    in the calibrated range, dashed beyond; plateau points as error bars; the truth dotted; T_ref
    marked; ``span`` (the record's temperatures) shaded.  The caller closes it."""
    plt = new_figure()
    T = np.asarray(term["temperature_c"])
    inside = np.asarray(term["in_range"], dtype=bool)
    # the boundary points belong to both pieces, so the solid and dashed lines meet
    edge = np.zeros_like(inside)
    edge[:-1] |= inside[:-1] & ~inside[1:]
    edge[1:] |= inside[1:] & ~inside[:-1]
    outside = ~inside | edge
    v = np.asarray(term["value"])
    s = None if term["sigma"] is None else np.asarray(term["sigma"])
    fig, ax = plt.subplots(figsize=(5.6, 4.0))
    if span is not None:
        ax.axvspan(span[0], span[1], color="0.85", alpha=0.6, lw=0, label="record's temperatures")
    for i, comp in enumerate(term["components"]):
        c = f"C{i}"
        if s is not None:
            ax.fill_between(T, v[:, i] - s[:, i], v[:, i] + s[:, i], where=inside, color=c, alpha=0.2, lw=0)
            if outside.any():
                ax.fill_between(T, v[:, i] - s[:, i], v[:, i] + s[:, i], where=outside, color=c, alpha=0.08, lw=0)
        ax.plot(T, np.where(inside, v[:, i], np.nan), color=c, lw=1.4, label=comp or term["title"])
        if outside.any():
            ax.plot(T, np.where(outside, v[:, i], np.nan), color=c, lw=1.1, ls="--")
        if "truth" in term:
            ax.plot(T, np.asarray(term["truth"])[:, i], color="k", lw=0.7, ls=":", zorder=3,
                    label="truth" if i == 0 else None)
        pts = [(p["temperature_c"], p["value"][i], None if p["sigma"] is None else p["sigma"][i]) for p in term["plateaus"]]
        if pts:
            x, y, e = zip(*pts)
            ax.errorbar(x, y, yerr=None if None in e else e, fmt="o", ms=3.5, color=c, capsize=2.5, lw=1.0, zorder=4,
                        label="plateaus ±1σ" if i == 0 else None)
    if inside.any():  # the ends of the calibrated range, where they lie inside the plot
        lo, hi = T[inside].min(), T[inside].max()
        for x in [lo] * bool(lo > T[0]) + [hi] * bool(hi < T[-1]):
            ax.axvline(x, color="0.5", lw=0.6, ls=":")
    ax.axvline(term["t_ref"], color="0.3", lw=0.7, ls="-.")
    ax.set(xlabel="temperature [°C]", ylabel=f"{term['title'].lower()} [{display_unit(term['unit'])}]",
           title=f"{term['title']} (T_ref {term['t_ref']:g} °C)")
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    first = [i for i, lab in enumerate(labels) if lab in term["components"] or lab == term["title"]]
    order = first + [i for i in range(len(labels)) if i not in first]  # the components, then the rest
    ax.legend([handles[i] for i in order], [labels[i] for i in order], fontsize=7,
              ncol=len(order) if len(order) <= 6 else -(-len(order) // 2),
              loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)
    fig.subplots_adjust(left=0.15, right=0.97, top=0.92, bottom=0.25)
    return fig


def coefficient_unit(unit: str, order: int) -> str:
    """Display spelling of a coefficient's unit: ``ppm`` order 2 -> ``ppm/°C²``."""
    return display_unit(unit) + "/°C" + {1: "", 2: "²", 3: "³"}.get(order, f"^{order}")


def thermal_section(label: str, data: dict) -> str:
    """HTML of one thermal model (:func:`thermal_data`): a figure per term with its caption, the
    coefficients with their 1σ and fit, and the dT/dt term."""
    plt = new_figure()
    span = data.get("record_span_c")
    figs = []
    for name, term in data["terms"].items():
        fig = thermal_figure(term, span)
        try:
            b64 = png_base64(fig)
        finally:
            plt.close(fig)
        figs.append(f"<figure><img alt='{escape(term['title'])} over temperature' src='data:image/png;base64,{b64}'/>"
                    f"<figcaption>{escape(term['caption'])}</figcaption></figure>")
    rows = []
    for name, term in data["terms"].items():
        comps = ", ".join(c for c in term["components"])
        for c in term["coefficients"]:
            rows.append([name if c["order"] == 1 else "", str(c["order"]), coefficient_unit(term["unit"], c["order"]) + f" ({comps})",
                         ", ".join(fmt_num(x) for x in c["value"]),
                         ", ".join(fmt_num(x) for x in c["sigma"]) if c["sigma"] is not None else "—",
                         fit_text(term["fit"], term["components"]) if c["order"] == 1 else ""])
    rate = data.get("rate")
    if rate is not None:
        rows.append([RATE_TERM[0], "dT/dt", RATE_DISPLAY + " (x, y, z)",
                     ", ".join(fmt_num(x) for x in rate["value"]),
                     ", ".join(fmt_num(x) for x in rate["sigma"]) if rate["sigma"] is not None else "—",
                     fit_text(rate["fit"], ("x", "y", "z"))])
    rng = f"{data['t_min']:g} .. {data['t_max']:g} °C"
    intro = (f"T_ref {data['t_ref']:g} °C, calibrated range {rng}, out of range: {data['out_of_range']}, sensor: "
             f"{data['sensor'] or 'mean of the record’s sensors'}. The parameter table above holds the values at T_ref.")
    if rate is not None:
        vs = ", ".join(f"{fmt_num(v)} ± {fmt_num(s)}" if s is not None else fmt_num(v)
                       for v, s in zip(rate["value"], rate["sigma"] or [None] * 3))
        intro += f" Gyro bias per rate of temperature change (x, y, z): {vs} {RATE_DISPLAY}."
    if data["constant"]:
        intro += " Not temperature-dependent in this model: " + ", ".join(data["constant"]) + "."
    return (f"<section class='thermal'><h2>Thermal model: {escape(label)}</h2><p class='thermal'>{escape(intro)}</p>"
            f"<div class='thermal-figs'>{''.join(figs)}</div>"
            + html_table(["term", "order", "unit", "value", "1σ", "fit"], rows) + "</section>")


def params_thermal(meta: dict, imu: ImuErrors, truth=None, span=None) -> dict | None:
    """:func:`thermal_data` of a parameter file (``meta`` of :func:`inscal.io.paramfile.load_params`, with
    ``thermal``, ``thermal_sigma``, ``thermal_fit``, ``sigma``; plateau points from ``meta["plateaus"]``
    or ``thermal_fit["plateaus"]``), None when it holds no thermal model."""
    model = meta.get("thermal")
    if model is None:
        return None
    return thermal_data(model, meta.get("thermal_sigma"), imu, meta.get("sigma"), meta.get("thermal_fit"),
                        params_plateaus(meta), truth, span=span)


def params_plateaus(meta: dict) -> list[PlateauPoint]:
    """The per-plateau points of a parameter file: ``meta["plateaus"]``, else the ``plateaus`` list of its
    ``[thermal.fit]`` table (SI values, the shape of the module docstring); :class:`PlateauError` if malformed."""
    plats = meta.get("plateaus")
    tfit = meta.get("thermal_fit")
    if plats is None and isinstance(tfit, dict):
        plats = tfit.get("plateaus")
    if plats is not None and not isinstance(plats, (list, tuple)):
        raise PlateauError(f"plateaus: expected a list of {{temperature_c, values, sigma}} tables, got {type(plats).__name__}")
    return plateau_points(plats)


def result_thermal(result, truth=None, span=None, covariance: dict | None = None) -> dict | None:
    """:func:`thermal_data` of a :class:`~inscal.calibrate.result.CalibrationResult` (its ``thermal``,
    ``thermal_sigma``, ``thermal_fit``, ``sigma`` and ``diagnostics["plateaus"]``), None without a thermal model."""
    if result.thermal is None:
        return None
    return thermal_data(result.thermal, result.thermal_sigma, result.imu, result.sigma, result.thermal_fit,
                        result.diagnostics.get("plateaus"), truth, covariance, span)
