"""A calibration as self-contained C99: a header and a source that compensate one sample on the target.

The template (package data, ``templates/inscal_compensation.{h,c}``) implements exactly what
``inscal compensate`` does with a parameter file (:meth:`inscal.core.error_model.ImuErrors.compensate`
on rates = increments / dt, and :meth:`inscal.core.thermal.ThermalModel.to_reference` before it)::

    thermal (optional):  N_0 = M_0 (I + E(T))^-1 (N(T) - b(T) dt) / (1 + K(T)) + b_0 dt
    linear (S16 eq. 3, 6):  w0 = M_g^-1 (dth/dt - eps),   f0 = M_a^-1 (dv/dt - nabla)
    time asynchrony, size effect's w-dot: from the neighbouring samples (centred differences)
    nonlinear (S16 eq. 8, 12, 9-11): the fixed point f = f0 - K2 f^(2) - Kx f^(x) - a_size(w, w-dot),
                                      w = w0 - G f, iterated to 1e-15 of max(1, |f0|)

The generated code keeps every parameter as a ``static const double`` printed with 17 significant
digits (the file's double exactly), uses no dynamic memory and no state, and includes only
``<math.h>`` and ``<stddef.h>``.  The comparison with the Python compensation is in
``tests/io/test_exports.py`` (compiled with the system's C compiler).
"""

from __future__ import annotations

import math
import re
from contextlib import ExitStack
from datetime import datetime, timezone
from importlib import resources
from pathlib import Path

import numpy as np

from inscal import __version__
from inscal.core.error_model import ImuErrors
from inscal.core.thermal import OUT_OF_RANGE, ThermalModel
from inscal.io.files import atomic_path

TEMPLATE = "templates/inscal_compensation"


def _num(x: float) -> str:
    x = float(x)
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "-HUGE_VAL"
    s = f"{x:.17g}"
    return s if any(c in s for c in ".en") else s + ".0"


def _arr(a) -> str:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        return "{" + ", ".join(_num(v) for v in a) + "}"
    return "{" + ", ".join(_arr(r) for r in a) + "}"


def _padded(c: np.ndarray, rows: int, cols: int) -> np.ndarray:
    out = np.zeros((rows, cols))
    out[:c.shape[0]] = c
    return out


def c_sources(imu: ImuErrors, thermal: ThermalModel | None, name: str = "inscal_compensation",
              params_file: str = "", method: str = "") -> tuple[str, str]:
    """The header and the source text for ``imu`` (and its ``thermal`` model, or None)."""
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        raise ValueError(f"{name!r} cannot name a C file and its guard (letters, digits, underscores)")
    th = thermal if thermal is not None else ThermalModel()
    neighbours = imu.has_asynchrony or bool(np.any(imu.accel_lever_arm))
    sub = {
        "NAME": name, "GUARD": name.upper() + "_H", "PREFIX": "inscal_", "VERSION": __version__,
        "CREATED": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "PARAMS_FILE": params_file.replace("*/", "* /") or "a parameter file", "METHOD": method or "?",
        "HAS_THERMAL": "1" if thermal is not None and not thermal.is_zero else "0",
        "NEEDS_NEIGHBOURS": "1" if neighbours else "0",
        "MGI": _arr(np.linalg.inv(imu.M_g)), "MAI": _arr(np.linalg.inv(imu.M_a)),
        "EPS": _arr(imu.gyro_bias), "NAB": _arr(imu.accel_bias), "G": _arr(imu.gyro_g_sensitivity),
        "K2": _arr(imu.accel_nonlinearity), "KX": _arr(imu.K_cross), "LEV": _arr(imu.accel_lever_arm),
        "TAU": _num(imu.time_asynchrony),
        "ITERATE": "1" if imu.has_nonlinear or np.any(imu.gyro_g_sensitivity) else "0",
        "HAS_LEVER": "1" if np.any(imu.accel_lever_arm) else "0",
        "T_REF": _num(th.t_ref), "T_MIN": _num(th.t_min), "T_MAX": _num(th.t_max),
        "POLICY": str(OUT_OF_RANGE.index(th.out_of_range)),
        "MG0": _arr(imu.M_g), "MA0": _arr(imu.M_a), "KG0": _arr(imu.gyro_scale_factor),
        "KA0": _arr(imu.accel_scale_factor), "EG0": _arr(imu.gyro_misalignment), "EA0": _arr(imu.accel_misalignment),
        "D_RATE": _arr(th.gyro_bias_rate),
    }
    for key, term, rows, cols in (("BG", "gyro_bias", 3, 3), ("KG", "gyro_scale_factor", 3, 3),
                                  ("EG", "gyro_misalignment", 1, 6), ("BA", "accel_bias", 3, 3),
                                  ("KA", "accel_scale_factor", 3, 3), ("EA", "accel_misalignment", 1, 6)):
        c = getattr(th, term)
        sub[f"N_{key}"] = str(c.shape[0])
        sub[f"C_{key}"] = _arr(_padded(c, rows, cols))
    out = []
    for ext in ("h", "c"):
        text = resources.files("inscal.io.exports").joinpath(f"{TEMPLATE}.{ext}").read_text(encoding="utf-8")
        text = re.sub(r"@([A-Z_0-9]+)@", lambda m: sub[m.group(1)], text)
        out.append(text)
    return out[0], out[1]


def export_c(imu: ImuErrors, thermal: ThermalModel | None, out, overwrite: bool = False, params_file: str = "",
             method: str = "") -> dict:
    """Write ``out`` (``NAME.c``) and ``NAME.h`` beside it, atomically (both or neither)."""
    out = Path(out)
    if out.suffix != ".c":
        raise ValueError(f"{out}: the C export writes NAME.c and NAME.h; give --out NAME.c")
    header, source = c_sources(imu, thermal, out.stem, params_file, method)
    hpath = out.with_suffix(".h")
    with ExitStack() as stack:
        ct = stack.enter_context(atomic_path(out, overwrite))
        ht = stack.enter_context(atomic_path(hpath, overwrite))
        ct.write_text(source, encoding="utf-8")
        ht.write_text(header, encoding="utf-8")
    return {"files": [str(out), str(hpath)], "thermal": thermal is not None and not thermal.is_zero,
            "neighbours": imu.has_asynchrony or bool(np.any(imu.accel_lever_arm))}
