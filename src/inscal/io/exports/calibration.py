"""``inscal export PARAMS --format kalibr|imucal|imu-tk|kf-gins|c``: a parameter file written in another tool's
convention (one module each in :mod:`inscal.io.exports`), atomically, with the terms it cannot hold; and
``inscal export noise.toml --format kalibr|kf-gins|matlab``: a noise model (``inscal noise --out``) as Kalibr's
``imu.yaml``, KF-GINS's ``imunoise`` block or MATLAB's ``gyroparams``/``accelparams``
(:mod:`inscal.io.exports.noise`)."""

from __future__ import annotations

import tomllib
from pathlib import Path

from inscal.io.exports.c import export_c
from inscal.io.exports.imucal import imucal_json
from inscal.io.exports.imutk import ACC_SUFFIX, GYRO_SUFFIX, imutk_files
from inscal.io.exports.kalibr import kalibr_yaml
from inscal.io.exports.kfgins import kfgins_yaml
from inscal.io.exports.noise import dropped, kalibr_imu_yaml, kfgins_imunoise, matlab_script
from inscal.io.files import atomic_path
from inscal.io.noisefile import FORMAT as NOISE_FORMAT
from inscal.io.noisefile import read_noise
from inscal.io.paramfile import load_params

#: the calibration export formats and the file each writes
CALIBRATION_FORMATS = {"kalibr": "YAML (imu0: M_accel, M_gyro, A, C_gyro_i[, rx_i ry_i rz_i])",
                       "imucal": "JSON (Ferraris calibration)",
                       "imu-tk": "NAME_acc.calib + NAME_gyro.calib (T, K, B of each triad)", "kf-gins": "YAML (initial IMU error blocks)",
                       "c": "C99 NAME.c + NAME.h"}
#: the noise-model export formats (a noise.toml) and the file each writes
NOISE_FORMATS = {"kalibr": "YAML (Kalibr imu.yaml: noise densities and random walks)",
                 "kf-gins": "YAML (KF-GINS imunoise block)", "matlab": "MATLAB script (gyroparams, accelparams)"}


def is_noise_file(path) -> bool:
    """Whether ``path`` is a noise model file (``format = "inscal-noise"``) rather than a parameter file."""
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8")).get("format") == NOISE_FORMAT
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False


def export_noise(path, out, fmt: str, overwrite: bool = False) -> dict:
    """Write the noise model file ``path`` to ``out`` in ``fmt`` (:data:`NOISE_FORMATS`); returns a summary
    (``dropped``: each kind of term the convention cannot hold, its channels and why, as in the file's comments)."""
    if fmt not in NOISE_FORMATS:
        raise ValueError(f"a noise model exports as {' | '.join(NOISE_FORMATS)}, not {fmt!r}")
    model, _meta = read_noise(path)
    text = {"kalibr": kalibr_imu_yaml, "kf-gins": kfgins_imunoise, "matlab": matlab_script}[fmt](model)
    with atomic_path(out, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return {"params": str(path), "format": fmt, "out": str(out), "method": "noise model",
            "dropped": dropped(model, fmt), "files": [str(out)]}


def export_calibration(params, out, fmt: str, overwrite: bool = False) -> dict:
    """Write the parameter file ``params`` to ``out`` in ``fmt``; returns a summary (``dropped``: the
    non-zero terms the convention cannot hold)."""
    params, out = Path(params), Path(out)
    if is_noise_file(params):
        return export_noise(params, out, fmt, overwrite)
    if fmt not in CALIBRATION_FORMATS:
        raise ValueError(f"unknown calibration export {fmt!r}; choose one of: {', '.join(CALIBRATION_FORMATS)}"
                         + (" (matlab exports a noise model, noise.toml)" if fmt == "matlab" else ""))
    imu, _gimbal, meta = load_params(params)
    thermal = meta.get("thermal")
    res = {"params": str(params), "format": fmt, "out": str(out), "method": meta.get("method", "")}
    if fmt == "c":
        res.update(export_c(imu, thermal, out, overwrite, params.name, meta.get("method", "")), dropped=[])
        return res
    if fmt == "imu-tk":
        acc, gyro, info = imutk_files(imu, thermal)
        gout = imutk_gyro_path(out)
        with atomic_path(out, overwrite) as tmp, atomic_path(gout, overwrite) as gtmp:
            tmp.write_text(acc, encoding="utf-8")
            gtmp.write_text(gyro, encoding="utf-8")
        res.update(info, files=[str(out), str(gout)])
        return res
    if fmt == "kalibr":
        text, info = kalibr_yaml(imu, thermal, source=params.name)
    elif fmt == "imucal":
        text, info = imucal_json(imu, thermal, comment=f"exported by inscal from {params.name}")
    else:
        text, info = kfgins_yaml(imu, meta.get("sigma"), thermal, source=params.name)
    with atomic_path(out, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    res.update(info, files=[str(out)])
    return res


def imutk_gyro_path(out) -> Path:
    """The gyro file beside the accelerometer file ``NAME_acc.calib`` (``--format imu-tk``): ``NAME_gyro.calib``."""
    out = Path(out)
    if not out.name.endswith(ACC_SUFFIX):
        raise ValueError(f"{out}: --format imu-tk writes NAME{ACC_SUFFIX} and NAME{GYRO_SUFFIX}: give --out NAME{ACC_SUFFIX}")
    return out.with_name(out.name[: -len(ACC_SUFFIX)] + GYRO_SUFFIX)
