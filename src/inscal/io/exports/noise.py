"""Exports of an identified noise model (:class:`inscal.core.noise_models.NoiseModel`) into the
conventions of other tools.  Each takes the three gyro channels ``gx gy gz`` and the three
accelerometer channels ``ax ay az`` and reduces them to one figure per sensor where the tool takes one
(the largest of the three axes: the conservative choice).

* **Kalibr** ``imu.yaml`` (ethz-asl/kalibr, "IMU Noise Model" wiki): continuous-time densities,
  ``gyroscope_noise_density`` [rad/s/sqrt(Hz)] = N, ``gyroscope_random_walk`` [rad/s^2/sqrt(Hz)] = K,
  ``accelerometer_noise_density`` [m/s^2/sqrt(Hz)], ``accelerometer_random_walk`` [m/s^3/sqrt(Hz)],
  ``update_rate`` [Hz].  A model without a random walk gives the one of its slowest Gauss-Markov term
  (sigma sqrt(2 / tc): the GM's driving noise, its short-time random walk), said in a comment.
* **KF-GINS** ``imunoise`` block (i2Nav-WHU/KF-GINS ``kf-gins.yaml``): ``arw`` [deg/sqrt(h)],
  ``vrw`` [m/s/sqrt(h)], ``gbstd`` [deg/h] and ``abstd`` [mGal] the stationary std of the
  Gauss-Markov biases, ``corrtime`` [h] their correlation time (one for all; the slowest GM's), per axis.
  ``gsstd``/``asstd`` (scale-factor std) come from a calibration, not a noise model: given or left out.
* **MATLAB** ``gyroparams`` / ``accelparams`` (Sensor Fusion and Tracking Toolbox, ``imuSensor``):
  ``NoiseDensity`` [(rad/s)/sqrt(Hz)], ``RandomWalk`` [(rad/s)*sqrt(Hz)], ``BiasInstability`` [rad/s]
  with ``BiasInstabilityCoefficients`` the AR(1) filter {num = 1, den = [1, -phi]} of the slowest
  GM (phi = exp(-dt/tc)): white noise of std ``BiasInstability`` = sigma sqrt(1 - phi^2) through it
  has the GM's stationary std sigma (per axis, accelerometers in m/s^2 units).  A bias instability
  without a GM maps to ``BiasInstability`` = B (the IEEE figure, as MATLAB's own Allan example sets
  it) with MATLAB's default coefficients [1, -0.5].

Every export names what it leaves out, and why (:func:`dropped`, :data:`WHY_DROPPED`): in the file's
comments and in the export's ``dropped`` list.  Kalibr holds white noise and a random walk only, so a
bias instability, a rate ramp, quantization and Gauss-Markov terms beside a random walk are dropped
(there is no honest random-walk equivalent of a flicker floor); KF-GINS holds white noise and one GM
bias per axis (no random walk, no BI); MATLAB holds white noise, random walk and one BiasInstability.
"""

from __future__ import annotations

import math

from inscal.core import noise_models as nm
from inscal.core import units

GYRO, ACCEL = ("gx", "gy", "gz"), ("ax", "ay", "az")
#: 1 mGal = 1e-5 m/s^2 (KF-GINS's accelerometer bias unit)
MGAL = 1e-5
#: MATLAB's default BiasInstabilityCoefficients denominator [1, -0.5] (imuSensor)
MATLAB_DEFAULT_PHI = 0.5


def _term(ch: nm.ChannelNoise, code: str):
    return [t for t in ch.terms if t.code == code]


def _slowest_gm(ch):
    gms = _term(ch, "GM")
    return max(gms, key=lambda t: t.tc) if gms else None


def _n(ch) -> float:
    w = _term(ch, "WN")
    return w[0].n if w else 0.0


def _rw(ch) -> tuple[float, bool]:
    """(K, taken from a GM)."""
    k = _term(ch, "RW")
    if k:
        return k[0].k, False
    g = _slowest_gm(ch)
    return (g.sigma * math.sqrt(2.0 / g.tc), True) if g else (0.0, False)


#: per export format, why each kind of term it cannot hold is left out (the kept ones: see :func:`_kept`)
WHY_DROPPED = {
    "kalibr": {"QN": "no quantization field", "BI": "no bias-instability field (Kalibr's bias is a random walk "
               "only; a flicker floor has no honest random-walk equivalent)", "DR": "no rate-ramp field",
               "GM": "no Gauss-Markov field (the bias is a random walk only)"},
    "kf-gins": {"QN": "no quantization field", "BI": "no bias-instability field (the bias is one Gauss-Markov "
                "process)", "RW": "no random-walk field (the bias is one Gauss-Markov process)",
                "DR": "no rate-ramp field", "GM": "one Gauss-Markov bias per axis (the slowest kept)"},
    "matlab": {"QN": "no angle-quantization field (Resolution is an output LSB)", "BI": "one BiasInstability "
               "field, taken by the Gauss-Markov term", "DR": "no rate-ramp field",
               "GM": "one BiasInstability filter per sensor (the slowest GM kept)"},
}


def _kept(fmt: str, ch: nm.ChannelNoise, t) -> bool:
    """Whether the export ``fmt`` holds the term ``t`` of channel ``ch`` (exactly or by its stated mapping)."""
    slow = _slowest_gm(ch)
    if t.code == "WN":
        return True
    if fmt == "kalibr":
        return t.code == "RW" or (t is slow and not _term(ch, "RW"))  # the GM's short-time random walk
    if fmt == "kf-gins":
        return t is slow
    return t.code == "RW" or t is slow or (t.code == "BI" and slow is None)  # matlab


def dropped(model: nm.NoiseModel, fmt: str) -> list[str]:
    """What the export ``fmt`` leaves out of ``model``, and why: one line per kind of term, naming the
    channels (empty when it holds every term)."""
    groups: dict = {}
    for ch in model.channels:
        for t in ch.terms:
            if not _kept(fmt, ch, t):
                groups.setdefault(t.code, []).append(ch.name)
    return [f"{code} of {', '.join(dict.fromkeys(names))}: {WHY_DROPPED[fmt][code]}" for code, names in groups.items()]


def _channels(model: nm.NoiseModel, names):
    try:
        return [model.channel(n) for n in names]
    except KeyError as exc:
        raise ValueError(f"the export needs the channels {', '.join(names)}: {exc.args[0]}") from None


def kalibr_imu_yaml(model: nm.NoiseModel, rostopic: str = "/imu0") -> str:
    """The text of a Kalibr ``imu.yaml``."""
    g, a = _channels(model, GYRO), _channels(model, ACCEL)
    gk = [_rw(c) for c in g]
    ak = [_rw(c) for c in a]
    notes = []
    if any(f for _, f in gk + ak):
        notes.append("# random walk from the slowest Gauss-Markov term (sigma*sqrt(2/tc)) where the model has none")
    notes += [f"# dropped: {d}" for d in dropped(model, "kalibr")]
    return "\n".join([
        "# Kalibr IMU noise model, written by inscal (continuous-time densities, SI; the largest axis)",
        *notes,
        f"rostopic: {rostopic}",
        f"update_rate: {model.rate_hz:.17g}  # Hz",
        f"gyroscope_noise_density: {max(_n(c) for c in g):.17g}  # rad/s/sqrt(Hz)",
        f"gyroscope_random_walk: {max(k for k, _ in gk):.17g}  # rad/s^2/sqrt(Hz)",
        f"accelerometer_noise_density: {max(_n(c) for c in a):.17g}  # m/s^2/sqrt(Hz)",
        f"accelerometer_random_walk: {max(k for k, _ in ak):.17g}  # m/s^3/sqrt(Hz)",
    ]) + "\n"


def _gm_or_zero(ch):
    g = _slowest_gm(ch)
    return (g.sigma, g.tc) if g else (0.0, math.inf)


def kfgins_imunoise(model: nm.NoiseModel, gsstd_ppm=None, asstd_ppm=None) -> str:
    """The text of KF-GINS's ``imunoise:`` block (YAML)."""
    g, a = _channels(model, GYRO), _channels(model, ACCEL)
    gb = [_gm_or_zero(c) for c in g]
    ab = [_gm_or_zero(c) for c in a]
    tcs = [tc for _, tc in gb + ab if math.isfinite(tc)]
    corr_h = (max(tcs) if tcs else 3600.0) / 3600.0

    def vec(vals):
        return "[" + ", ".join(f"{v:.10g}" for v in vals) + "]"

    lines = [f"# dropped: {d}" for d in dropped(model, "kf-gins")] + ["imunoise:",
             f"    arw: {vec(units.from_si([_n(c) for c in g], 'deg/sqrt(h)'))}  # [deg/sqrt(hr)]",
             f"    vrw: {vec(units.from_si([_n(c) for c in a], 'm/s/sqrt(h)'))}  # [m/s/sqrt(hr)]",
             f"    gbstd: {vec(units.from_si([s for s, _ in gb], 'deg/h'))}  # [deg/hr]",
             f"    abstd: {vec([s / MGAL for s, _ in ab])}  # [mGal]"]
    if gsstd_ppm is not None:
        lines.append(f"    gsstd: {vec(gsstd_ppm)}  # [ppm]")
    if asstd_ppm is not None:
        lines.append(f"    asstd: {vec(asstd_ppm)}  # [ppm]")
    lines.append(f"    corrtime: {corr_h:.10g}  # [hr]")
    return "\n".join(lines) + "\n"


def matlab_params(model: nm.NoiseModel) -> dict:
    """``{"gyroparams": {...}, "accelparams": {...}}``: the name-value fields of MATLAB's
    ``gyroparams``/``accelparams`` (per-axis vectors, SI), ready for a MATLAB script or JSON."""
    dt = 1.0 / model.rate_hz
    out = {}
    for key, names in (("gyroparams", GYRO), ("accelparams", ACCEL)):
        chans = _channels(model, names)
        bi, phis = [], []
        for c in chans:
            gm = _slowest_gm(c)
            phi = math.exp(-dt / gm.tc) if gm else 0.0
            flicker = _term(c, "BI")
            # a bias instability without a GM: MATLAB's BiasInstability is the IEEE figure B itself
            bi.append(gm.sigma * math.sqrt(1 - phi * phi) if gm else (flicker[0].b if flicker else 0.0))
            phis.append(phi)
        phi = max(phis) if any(phis) else (MATLAB_DEFAULT_PHI if any(_term(c, "BI") for c in chans) else 0.0)
        out[key] = {"NoiseDensity": [_n(c) for c in chans],
                    "RandomWalk": [_term(c, "RW")[0].k if _term(c, "RW") else 0.0 for c in chans],
                    "BiasInstability": bi,
                    "BiasInstabilityCoefficients": {"Numerator": 1.0, "Denominator": [1.0, -phi]}}
    return out


def matlab_script(model: nm.NoiseModel) -> str:
    """A MATLAB snippet that builds the two parameter objects."""
    p = matlab_params(model)
    lines = [f"% inscal noise model at {model.rate_hz:g} Hz (SI)"] + [f"% dropped: {d}" for d in dropped(model, "matlab")]
    mapped = [c.name for c in model.channels if _term(c, "BI") and not _term(c, "GM")]
    if mapped:
        lines.append(f"% mapped: BI of {', '.join(mapped)} as BiasInstability = B (the IEEE figure) with MATLAB's "
                     "default filter [1 -0.5] where the sensor has no GM: not the flicker spectrum")
    for key, d in p.items():
        c = d["BiasInstabilityCoefficients"]
        args = ", ".join(f"'{k}', [{' '.join(f'{v:.10g}' for v in d[k])}]" for k in ("NoiseDensity", "RandomWalk", "BiasInstability"))
        lines.append(f"{key[:-6]} = {key}({args}, 'BiasInstabilityCoefficients', "
                     f"struct('Numerator', {c['Numerator']:g}, 'Denominator', [1 {c['Denominator'][1]:.10g}]));")
    return "\n".join(lines) + "\n"
