"""Built-in simulation scenarios and custom scenarios from TOML files.

Built-in (``inscal simulate NAME``):

``s16``
    S16 section 4.1: gyro and accelerometer scale factors 300 ppm, misalignments 180"
    (S16 form: 3 gyro angles in the gyro-defined m-frame, 6 accelerometer angles),
    gyro bias 0.05 deg/h, ARW 0.00005 deg/sqrt(h), accelerometer bias 200 ug, white noise
    1 ug/sqrt(Hz), g-sensitivity 0.001 deg/h/g (all 9 terms), nonlinearity and
    cross-coupling 300 ug/g^2, lever arms 2 cm, turntable (mount) attitude error 1"
    on each axis; S16 Table 1 path (18 rotations, 5 deg/s, 180 s dwell), 100 Hz,
    latitude 30 deg N (S16 does not state its site; stated here).
``n25``
    N25 section 5: site 120.664265 E, 30.686651 N; carrier (mount) attitude
    [0.1, 0.1, 20] deg; ARW 0.02 deg/sqrt(h), VRW 20 ug/sqrt(Hz); gimbal
    non-orthogonality 20"; FOG-grade IMU errors (N25 Table 2 is not in the text; the
    values are :data:`N25_ERRORS`); twelve positions of 100 s at 4 deg/s plus CW/CCW
    rate tests at 10 deg/s.
``static``, ``static-24h``
    Static base, IMU level and E-N-U, N25 site, error-free (``static-24h``: 24 h): a
    perfect IMU, the reference run for the navigator (compensating it adds errors).
``n25-static``
    The ``n25`` IMU errors and noise on a static base (1 h by default, ``--duration-h``):
    the record for ``inscal allan`` and for static navigation of a real-looking IMU.
``rotmod16``, ``rotmod16-6h``
    16-sequence rotation modulation (300 s per position, 10 deg/s) at the N25 site and
    mount attitude, error-free (``rotmod16-6h``: 6 h).
``n25-rotmod``
    The ``n25`` IMU errors, gimbal non-orthogonality, mount attitude and noise under
    16-sequence rotation modulation (6 h by default): the N25 section 6 navigation check.
``psins19``
    PSINS-style 19-position systematic calibration (:func:`inscal.core.turntable.psins19`: 18
    turns of 90 deg at 10 deg/s, 50 deg/s^2, 9.2 s each, 20-90 s stops, 1035.6 s), 100 Hz,
    site 34 N, 108 E, 380 m; no gimbal non-orthogonality, zero mount attitude.  A
    navigation-grade IMU whose truth includes the quadratic terms and lever arms
    (:data:`PSINS19_ERRORS`), given in the S16 compensation form with the m-frame equal to
    the s-frame (gyro misalignment lower-triangular, 3 angles) like ``s16``, so a filter
    estimating in the gyro-defined frame compares with the truth without a rotation:
    gyro scale factors 20-40 ppm, misalignments 10-35", gyro bias 0.015-0.035 deg/h,
    g-sensitivity 1e-4 to 8e-4 deg/h/g on 5 entries, accelerometer bias 60-95 ug, scale
    factors 60-95 ppm, nonlinearity 15-25 ug/g^2, cross-coupling 10-28 ug/g^2, lever arms
    [2.0, 3.0, -1.5] cm along the axes.  Noise of a navigation-grade FOG IMU: ARW
    0.002 deg/sqrt(h), VRW 5 ug/sqrt(Hz).
``s16-table3``
    An ultra-high-accuracy IMU (the "0.1 nmi / 5 d" INS of S16 section 4.3) whose truth
    includes the extra terms at the magnitudes of S16 Table 3 (the calibrated values of S16's
    real dual-axis RINS), in the S16 form with the m-frame equal to the s-frame like ``s16``
    (:data:`S16_TABLE3_ERRORS`): g-sensitivity G = 1e-5 deg/h/g x [[0.09, 0.25, -0.22],
    [0.35, 0.81, -0.24], [-0.07, -0.50, -1.02]]; nonlinearity K_a2 = [17.1, -20.4, 25.2]
    ug/g^2; cross-coupling [xy, xz, yx, yz, zx, zy] = [-2.0, -22.6, 7.8, 16.5, -0.5, 1.6]
    ug/g^2; lever arms [-4.1, 2.2, -2.4] cm (Table 3's numbers taken as inscal lever arms,
    i.e. accelerometer positions; S16's printed eq. 12 sign would report their negatives:
    the sign is immaterial here).  Linear errors of a real unit before calibration (not from
    S16; chosen "tens of ppm / arcsec"): gyro scale factors [20, -15, 25] ppm, gyro
    misalignment gamma [yz, zx, zy] = [15, -20, 10]", gyro bias [0.010, -0.008, 0.012] deg/h;
    accelerometer scale factors [40, -30, 50] ppm, misalignment alpha [xy, xz, yx, yz, zx,
    zy] = [20, -25, 15, -10, 30, -20]", bias [50, -40, 60] ug.  Noise (:data:`S16_TABLE3_NOISE`):
    ARW 5e-6 deg/sqrt(h), VRW 0.5 ug/sqrt(Hz), no bias instability.  Why: S16 expects atomic
    gyros better than 5e-6 deg/h; the 5-day position error that ARW N alone leaves in free
    inertial navigation grows about R N sqrt(t) (6 m here), and 0.5 ug/sqrt(Hz) is a good quartz
    accelerometer (its effect is Schuler-bounded): navigating 5 days with the true parameters
    and this noise leaves 10-21 m (0.005-0.011 nmi, :mod:`inscal.analysis.nav5d` with
    ``--nav-noise``), so the sensors are those of an INS well inside 0.1 nmi / 5 d and what the
    calibration leaves decides the error.
    Turntable (mount) attitude error 1" on each axis and site 30 N, 114 E as ``s16``;
    S16 Table 1 path, 100 Hz.
``handheld-mems``, ``handheld-tactical``, ``handheld-navigation``
    A hand-held session without a turntable (:mod:`inscal.sim.handheld`): 12 random still poses of
    4 s joined by 3-s minimum-jerk rotations with a 0.3 deg, 8 Hz tremor, 100 Hz, N25 site; no gimbal
    angles in the record (for ``calibrate --method multi-position``).  The IMU errors and noise of
    :data:`HANDHELD_GRADES` (illustrative magnitudes of each grade): scale factors 3000 / 300 / 50 ppm,
    misalignments 400 / 60 / 10 arcsec, gyro bias 1000 / 5 / 0.01 deg/h, accelerometer bias
    5000 / 500 / 50 ug, ARW 0.3 / 0.1 / 0.002 deg/sqrt(h), VRW 100 / 20 / 2 ug/sqrt(Hz).
``ferraris-mems``
    A Ferraris session (:class:`inscal.sim.handheld.FerrarisMotion`, laid out like imucal's example):
    the six faces held 4-7 s, then a whole turn about the vertical on the +x, +y and +z faces between
    poses of 1.0-1.5 s (the turns closing within 0.2 deg rms), 3-s moves, every face tilted by 0.3 deg
    rms, 102.4 Hz, N25 site, the ``mems`` errors and noise of :data:`HANDHELD_GRADES` (for ``calibrate
    --method ferraris``).
``thermal-plateaus``, ``thermal-plateaus-s16``, ``thermal-ramp``, ``thermal-cycle``, ``thermal-warmup``
    Temperature (beyond both papers).  The IMU errors follow the temperature with the thermal
    model :data:`THERMAL_ERRORS` (T_ref 20 degC, valid -40 .. +60 degC).  **Its magnitudes are
    illustrative** (those of a navigation-grade FOG IMU in an order of magnitude: gyro bias
    0.002 deg/h/degC, scale factors 0.5-2 ppm/degC, accelerometer bias 5 ug/degC, a gyro bias of
    0.02 deg/h per degC/min of temperature change); a real unit's must come from its own calibration.
    The temperature is recorded by one sensor at 1 Hz (/temperature).

    * ``thermal-plateaus``: the ``n25`` IMU, gimbal and noise; a thermal chamber at five plateaus
      (-40, -15, 10, 35, 60 degC), starting soaked at -40 degC, ramping 1 degC/min between them and
      soaking 30 min on each (the turntable resting at position 1), then the N25 twelve-position path
      with rate tests at each plateau.
    * ``thermal-plateaus-s16``: the same chamber cycle with the ``s16`` IMU, noise and S16 Table 1
      path at each plateau (the systematic filter per plateau).
    * ``thermal-ramp``: the ``s16`` IMU and noise; the S16 Table 1 path twice, without a stop, while
      the chamber holds -40 degC for 10 min, ramps to +60 degC at 1 degC/min and holds.
    * ``thermal-cycle``: the ``s16`` IMU and noise; the S16 Table 1 path four times, without a stop, while
      the chamber holds -40 degC for 10 min, ramps to +60 degC at 1 degC/min, holds 10 min and ramps back
      (the rest at -40 degC): each temperature is crossed at +1 and -1 degC/min, which separates the
      gyro bias's dT/dt term from its polynomial in T.
    * ``thermal-warmup``: the ``s16`` IMU and noise (a quiet navigation-grade unit: the ``n25`` noise
      alone would put a 2-h navigation kilometres off and hide the thermal errors) on a static base at
      the S16 site for 2 h (``--duration-h``) while the IMU warms up from 20 to 45 degC after turn-on
      (time constant 20 min).
``s16-gimbal``
    The ``s16`` scenario (S16 section 4.1 IMU errors and noise, S16 Table 1 path, 100 Hz, 30 N)
    on a gimbal with N25's geometry: non-orthogonality 20" and mount (carrier) attitude
    [0.1, 0.1, 20] deg (N25 section 5), encoders recorded with 1" white noise.  The case of
    the ``unified`` method (S16 filter + gimbal states + encoder attitude).

Custom scenario files (TOML; values in field units, see ``errors.PARAMETERS``)::

    base = "n25"                    # optional: start from a built-in scenario
    [scenario]
    name = "my-bench"
    rate_hz = 200
    duration_h = 2.0                # for static/rotmod paths
    [site]
    latitude_deg = 45.0
    longitude_deg = 7.6
    height_m = 250.0
    [errors]                        # bare value = field unit; or {value = ..., unit = "..."}
    gyro_bias = [0.01, -0.02, 0.005]
    gimbal_nonorthogonality = 15
    mount_attitude = {value = [0.1, 0.1, 20], unit = "deg"}
    [noise]
    arw = 0.02
    vrw = 20
    [path]
    builtin = "n25-twelve"          # or: name, accel_dps2, closed, moves = [{axis, angle_deg, rate_dps, dwell_s}, ...]
    [thermal]                       # the IMU errors follow the temperature (inscal.core.thermal); the layout of
    t_ref = 20.0                    #   a parameter file's [thermal] (its sigma and [thermal.fit] are ignored)
    t_min = -40.0                   # validity range, degC
    t_max = 60.0
    [[thermal.terms.gyro_bias]]     # one table per order (1 .. 3), unit <unit>/degC^order
    order = 1
    value = [0.002, -0.0015, 0.0025]
    unit = "deg/h/degC"
    [[thermal.terms.gyro_bias_rate]]  # the gyro bias per dT/dt (order 1 only)
    order = 1
    value = [0.02, -0.015, 0.025]
    unit = "deg/h/(degC/min)"
    [temperature]                   # the IMU temperature over time (needed with [thermal]); degC
    start_c = -40.0
    pieces = [{kind = "hold", duration_s = 600},                    # hold: duration_s
              {kind = "ramp", target_c = 60, rate_c_per_min = 1},   # ramp: target_c at rate_c_per_min
              {kind = "approach", target_c = 45, tau_s = 1200, duration_s = 3600}]  # exponential approach
    [temperature.sensor]            # how /temperature is recorded (default: one sensor "imu", 1 Hz, exact)
    names = ["imu", "case"]
    rate_hz = 1.0
    offsets_c = [0.0, -1.5]         # one per name (default 0)
    noise_c = 0.01                  # white noise, degC (drawn from the simulation's generator)
    quantum_c = 0.0625              # quantization, degC

A base scenario's thermal model, temperature profile and sensor carry over unless the file gives
them: ``[thermal]`` replaces the model as a whole, ``start_c`` (with ``pieces``) the profile, and the
keys of ``[temperature.sensor]`` those of the sensor (new ``names`` without ``offsets_c``: zero offsets).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from inscal import SCHEMA_VERSION
from inscal.core import units
from inscal.core.earth import GravityModel, Site, parse_gravity
from inscal.core.error_model import (
    GimbalErrors,
    ImuErrors,
    ImuNoise,
    S16Parameters,
    errors_from_field,
    errors_to_field,
    from_s16,
    noise_from_field,
)
from inscal.core.turntable import (
    BUILTIN_PATHS,
    PathError,
    RotationPath,
    n25_twelve,
    psins19,
    rotmod16,
    s16_table1,
    static,
)
from inscal.core.thermal import ThermalModel, thermal_from_field
from inscal.core.turntable import Move
from inscal.core.units import DEG
from inscal.core.noise_models import NoiseModel
from inscal.io.noisefile import NoiseFileError, read_noise
from inscal.io.tomlfile import read_toml
from inscal.sim.handheld import FerrarisMotion, HandheldMotion
from inscal.sim.simulate import Scenario
from inscal.sim.thermal import PIECE_KINDS, Piece, TemperatureProfile, TemperatureSensor, plateaus

N25_SITE = Site(latitude=30.686651 * DEG, longitude=120.664265 * DEG, height=0.0)
S16_SITE = Site(latitude=30.0 * DEG, longitude=114.0 * DEG, height=0.0)

#: FOG-grade IMU errors chosen for the N25 scenario (field units).
N25_ERRORS = {
    "gyro_scale_factor": [50.0, -40.0, 30.0],
    "gyro_misalignment": [20.0, -15.0, 10.0, -25.0, 15.0, -10.0],
    "gyro_bias": [0.02, -0.03, 0.015],
    "accel_scale_factor": [80.0, -60.0, 100.0],
    "accel_misalignment": [30.0, -20.0, 25.0, -35.0, 20.0, -15.0],
    "accel_bias": [50.0, -80.0, 100.0],
    "gimbal_nonorthogonality": 20.0,
    "mount_attitude": {"value": [0.1, 0.1, 20.0], "unit": "deg"},
}
N25_NOISE = {"arw": 0.02, "vrw": 20.0}

#: Site of the ``psins19`` scenario (34 N, 108 E, 380 m).
PSINS19_SITE = Site(latitude=34.0 * DEG, longitude=108.0 * DEG, height=380.0)

#: Navigation-grade IMU errors of the ``psins19`` scenario, in the S16 compensation form
#: (:class:`~inscal.core.error_model.S16Parameters`, m-frame = s-frame), field units.  Keys are the
#: S16Parameters fields: ``K_g``/``K_a`` are given as ``K - 1`` in ppm; ``gamma`` = [yz, zx, zy]
#: and ``alpha`` = [xy, xz, yx, yz, zx, zy] in arcsec; ``G`` (3x3, rows: gyro x, y, z) in
#: deg/h/g; ``K_a2`` = [xx, yy, zz] and ``K_cross`` = [xy, xz, yx, yz, zx, zy] (the entries of
#: S16 eq. 12: x gets ``Kxy fx fy + Kxz fx fz`` ...) in ug/g^2; ``lever_arm`` = [rx, ry, rz]
#: along each accelerometer's own axis in cm.
PSINS19_ERRORS = {
    "K_g": {"value": [30.0, -20.0, 40.0], "unit": "ppm"},
    "gamma": {"value": [20.0, -30.0, 15.0], "unit": "arcsec"},
    "b_g": {"value": [0.02, -0.035, 0.015], "unit": "deg/h"},
    "G": {"value": [[5e-4, 0.0, 2e-4], [0.0, -3e-4, 0.0], [0.0, 1e-4, 8e-4]], "unit": "deg/h/g"},
    "K_a": {"value": [80.0, -60.0, 95.0], "unit": "ppm"},
    "alpha": {"value": [25.0, -15.0, 30.0, -20.0, 10.0, -35.0], "unit": "arcsec"},
    "b_a": {"value": [60.0, -80.0, 95.0], "unit": "ug"},
    "K_a2": {"value": [15.0, -25.0, 20.0], "unit": "ug/g^2"},
    "K_cross": {"value": [12.0, -18.0, 22.0, -10.0, 28.0, -15.0], "unit": "ug/g^2"},
    "lever_arm": {"value": [2.0, 3.0, -1.5], "unit": "cm"},
}
#: Noise of the ``psins19`` scenario (navigation-grade FOG IMU), field units.
PSINS19_NOISE = {"arw": 0.002, "vrw": 5.0}

#: IMU errors of the ``s16-table3`` scenario in the S16 compensation form (m-frame = s-frame),
#: field units, keys and layout as :data:`PSINS19_ERRORS`.  G, K_a2, K_cross and lever_arm are
#: S16 Table 3 (the calibrated extra terms of S16's real dual-axis RINS); the linear terms are
#: those of a real unit before calibration (chosen, not from S16).
S16_TABLE3_ERRORS = {
    "K_g": {"value": [20.0, -15.0, 25.0], "unit": "ppm"},
    "gamma": {"value": [15.0, -20.0, 10.0], "unit": "arcsec"},
    "b_g": {"value": [0.010, -0.008, 0.012], "unit": "deg/h"},
    "G": {"value": [[0.09e-5, 0.25e-5, -0.22e-5], [0.35e-5, 0.81e-5, -0.24e-5], [-0.07e-5, -0.50e-5, -1.02e-5]],
          "unit": "deg/h/g"},
    "K_a": {"value": [40.0, -30.0, 50.0], "unit": "ppm"},
    "alpha": {"value": [20.0, -25.0, 15.0, -10.0, 30.0, -20.0], "unit": "arcsec"},
    "b_a": {"value": [50.0, -40.0, 60.0], "unit": "ug"},
    "K_a2": {"value": [17.1, -20.4, 25.2], "unit": "ug/g^2"},
    "K_cross": {"value": [-2.0, -22.6, 7.8, 16.5, -0.5, 1.6], "unit": "ug/g^2"},
    "lever_arm": {"value": [-4.1, 2.2, -2.4], "unit": "cm"},
}
#: Noise of the ``s16-table3`` scenario (an INS at the 0.1 nmi / 5 d level), field units.
S16_TABLE3_NOISE = {"arw": 5e-6, "vrw": 0.5}


def s16_errors() -> ImuErrors:
    """S16 section 4.1 error values, expressed in the S16 form then converted (m-frame = s-frame)."""
    sf, mis = 300e-6, units.to_si(180.0, "arcsec")
    ug, ug_g2 = units.to_si(1.0, "ug"), units.to_si(1.0, "ug/g^2")
    s16 = S16Parameters(
        K_g=np.full(3, 1.0 + sf), gamma=np.full(3, mis), b_g=np.full(3, units.to_si(0.05, "deg/h")),
        G=np.full((3, 3), units.to_si(0.001, "deg/h/g")),
        K_a=np.full(3, 1.0 + sf), alpha=np.full(6, mis), b_a=np.full(3, 200 * ug),
        K_a2=np.full(3, 300 * ug_g2), K_cross=np.zeros((3, 3)), lever_arm=np.full(3, 0.02),
    )
    kc = 300 * ug_g2
    s16 = replace(s16, K_cross=np.array([[kc, kc, 0.0], [kc, 0.0, kc], [0.0, kc, kc]]))
    return from_s16(s16)


def _s16_form(table: dict) -> S16Parameters:
    """A field-unit table in the :data:`PSINS19_ERRORS` layout as :class:`~inscal.core.error_model.S16Parameters` (SI)."""
    v = {k: units.to_si(e["value"], e["unit"]) for k, e in table.items()}
    kx = v["K_cross"]  # [xy, xz, yx, yz, zx, zy] -> S16 eq. 12 rows
    return S16Parameters(
        K_g=1.0 + v["K_g"], gamma=v["gamma"], b_g=v["b_g"], G=v["G"],
        K_a=1.0 + v["K_a"], alpha=v["alpha"], b_a=v["b_a"], K_a2=v["K_a2"],
        K_cross=np.array([[kx[0], kx[1], 0.0], [kx[2], 0.0, kx[3]], [0.0, kx[4], kx[5]]]),
        lever_arm=v["lever_arm"],
    )


def psins19_s16() -> S16Parameters:
    """:data:`PSINS19_ERRORS` as :class:`~inscal.core.error_model.S16Parameters` (SI; m-frame = s-frame)."""
    return _s16_form(PSINS19_ERRORS)


def s16_table3_s16() -> S16Parameters:
    """:data:`S16_TABLE3_ERRORS` as :class:`~inscal.core.error_model.S16Parameters` (SI; m-frame = s-frame)."""
    return _s16_form(S16_TABLE3_ERRORS)


def s16_table3_errors() -> ImuErrors:
    """The ``s16-table3`` IMU errors in the canonical form (``from_s16`` with ``C_s^m = I``)."""
    return from_s16(s16_table3_s16())


def psins19_errors() -> ImuErrors:
    """The ``psins19`` IMU errors in the canonical form (``from_s16`` with ``C_s^m = I``)."""
    return from_s16(psins19_s16())


def _psins19() -> Scenario:
    return Scenario("psins19", psins19(), PSINS19_SITE, imu=psins19_errors(), gimbal=GimbalErrors(),
                    noise=noise_from_field(PSINS19_NOISE), rate_hz=100.0)


def _s16() -> Scenario:
    return Scenario(
        "s16", s16_table1(), S16_SITE, imu=s16_errors(),
        gimbal=GimbalErrors(0.0, units.to_si([1.0, 1.0, 1.0], "arcsec")),
        noise=ImuNoise(arw=units.to_si(0.00005, "deg/sqrt(h)"), vrw=units.to_si(1.0, "ug/sqrt(Hz)")),
        rate_hz=100.0,
    )


def _s16_table3() -> Scenario:
    return Scenario("s16-table3", s16_table1(), S16_SITE, imu=s16_table3_errors(),
                    gimbal=GimbalErrors(0.0, units.to_si([1.0, 1.0, 1.0], "arcsec")),
                    noise=noise_from_field(S16_TABLE3_NOISE), rate_hz=100.0)


def _s16_gimbal() -> Scenario:
    base = _s16()
    gim = GimbalErrors(units.to_si(20.0, "arcsec"), units.to_si([0.1, 0.1, 20.0], "deg"))
    return replace(base, name="s16-gimbal", gimbal=gim,
                   noise=replace(base.noise, encoder_noise=units.to_si(1.0, "arcsec")))


def _n25() -> Scenario:
    imu, gim = errors_from_field(N25_ERRORS)
    return Scenario("n25", n25_twelve(), N25_SITE, imu=imu, gimbal=gim, noise=noise_from_field(N25_NOISE), rate_hz=100.0)


#: per grade: scale factor, misalignment [arcsec], gyro bias [deg/h], accel bias [ug], ARW [deg/sqrt(h)], VRW
#: [ug/sqrt(Hz)] (illustrative magnitudes; the signs and the spread over the axes are fixed patterns)
HANDHELD_GRADES = {"mems": (3000.0, 400.0, 1000.0, 5000.0, 0.3, 100.0),
                   "tactical": (300.0, 60.0, 5.0, 500.0, 0.1, 20.0),
                   "navigation": (50.0, 10.0, 0.01, 50.0, 0.002, 2.0)}


def _handheld(grade: str) -> Scenario:
    sf, mis, gb, ab, arw, vrw = HANDHELD_GRADES[grade]
    pat3, pat6 = [1.0, -0.7, 0.4], [1.0, -0.8, 0.6, -0.5, 0.3, -0.9]
    imu, gim = errors_from_field({
        "gyro_scale_factor": {"value": [sf * c for c in pat3], "unit": "ppm"},
        "gyro_misalignment": {"value": [mis * c for c in pat6], "unit": "arcsec"},
        "gyro_bias": {"value": [gb * c for c in pat3[::-1]], "unit": "deg/h"},
        "accel_scale_factor": {"value": [-sf * c for c in pat3], "unit": "ppm"},
        "accel_misalignment": {"value": [mis * c for c in pat6[::-1]], "unit": "arcsec"},
        "accel_bias": {"value": [ab * c for c in pat3], "unit": "ug"}})
    noise = noise_from_field({"arw": {"value": arw, "unit": "deg/sqrt(h)"}, "vrw": {"value": vrw, "unit": "ug/sqrt(Hz)"}})
    motion = HandheldMotion()
    return Scenario(f"handheld-{grade}", static(motion.duration), N25_SITE, imu=imu, gimbal=gim, noise=noise,
                    rate_hz=100.0, motion=motion)


def _ferraris() -> Scenario:
    """The Ferraris session of :class:`FerrarisMotion` (tilted faces) with the ``mems`` hand-held errors."""
    motion = FerrarisMotion()
    return replace(_handheld("mems"), name="ferraris-mems", path=static(motion.duration), rate_hz=102.4,
                   motion=motion)


def _static(duration_s: float = 3600.0) -> Scenario:
    return Scenario("static", static(duration_s), N25_SITE, rate_hz=100.0)


def _rotmod(duration_s: float = 6 * 3600.0) -> Scenario:
    _, gim = errors_from_field({"mount_attitude": N25_ERRORS["mount_attitude"]})
    return Scenario("rotmod16", rotmod16(duration_s), N25_SITE, gimbal=gim, rate_hz=100.0)


def _n25_static(duration_s: float = 3600.0) -> Scenario:
    """The N25 IMU errors, mount attitude and noise on a static base."""
    return replace(_n25(), name="n25-static", path=static(duration_s))


def _n25_rotmod(duration_s: float = 6 * 3600.0) -> Scenario:
    """The N25 IMU, gimbal and noise under 16-sequence rotation modulation (N25 section 6 navigation check)."""
    base = _n25()
    return replace(base, name="n25-rotmod", path=rotmod16(duration_s))


# ---------------------------------------------------------------------------- temperature
#: The thermal model of the built-in thermal scenarios (field units; illustrative magnitudes, see the
#: module docstring): coefficient rows of order 1, 2, 3 per term, T_ref 20 degC, valid -40 .. +60 degC.
THERMAL_ERRORS = {
    "t_ref": 20.0, "t_min": -40.0, "t_max": 60.0,
    "terms": {
        "gyro_bias": [{"order": 1, "value": [0.002, -0.0015, 0.0025], "unit": "deg/h/degC"},
                      {"order": 2, "value": [2e-5, -1e-5, 1.5e-5], "unit": "deg/h/degC^2"}],
        "gyro_scale_factor": [{"order": 1, "value": [0.5, -0.3, 0.4], "unit": "ppm/degC"},
                              {"order": 2, "value": [0.005, 0.004, -0.003], "unit": "ppm/degC^2"}],
        "accel_bias": [{"order": 1, "value": [5.0, -4.0, 6.0], "unit": "ug/degC"},
                       {"order": 2, "value": [0.05, 0.03, -0.04], "unit": "ug/degC^2"},
                       {"order": 3, "value": [5e-4, -3e-4, 4e-4], "unit": "ug/degC^3"}],
        "accel_scale_factor": [{"order": 1, "value": [2.0, -1.5, 1.0], "unit": "ppm/degC"},
                               {"order": 2, "value": [0.02, -0.01, 0.015], "unit": "ppm/degC^2"}],
        "gyro_bias_rate": [{"order": 1, "value": [0.02, -0.015, 0.025], "unit": "deg/h/(degC/min)"}],
    },
}
#: the chamber cycle of the plateau scenarios
THERMAL_PLATEAUS_C = (-40.0, -15.0, 10.0, 35.0, 60.0)
THERMAL_RAMP_C_PER_MIN = 1.0
THERMAL_SOAK_S = 1800.0
#: label of the chamber's transition moves (the turntable resting while the chamber ramps and soaks)
CHAMBER_LABEL = "chamber"


def thermal_model() -> ThermalModel:
    """:data:`THERMAL_ERRORS` in SI."""
    return thermal_from_field(THERMAL_ERRORS)[0]


def thermal_plateau_path(base: RotationPath, levels_c=THERMAL_PLATEAUS_C, rate_c_per_min: float = THERMAL_RAMP_C_PER_MIN,
                         soak_s: float = THERMAL_SOAK_S) -> tuple[RotationPath, TemperatureProfile]:
    """``base`` run once at each plateau of a chamber cycle that starts soaked at ``levels_c[0]``: between
    plateaus the turntable rests (a ``"none"`` move labelled :data:`CHAMBER_LABEL`) for the ramp and the
    soak.  ``base`` must be closed (each copy starts where the last ended); its initial dwell is kept."""
    if not base.closed:
        raise ScenarioError(f"path {base.name!r} is not closed: it cannot be repeated at each plateau")
    d = base.duration
    profile, _ = plateaus(levels_c, soak_s, rate_c_per_min, start_c=levels_c[0], dwell_s=d)
    # the first plateau starts soaked: drop its soak from the profile (the record starts on the plateau)
    pieces = list(profile.pieces)
    if soak_s > 0:
        pieces.pop(0)
    profile = TemperatureProfile(levels_c[0], tuple(pieces))
    moves: list[Move] = []
    for k, lev in enumerate(levels_c):
        if k:
            wait = abs(lev - levels_c[k - 1]) / (rate_c_per_min / 60.0) + soak_s + base.initial_dwell
            moves.append(Move("none", dwell=wait, label=f"{CHAMBER_LABEL}: to {lev:g} degC"))
        moves += list(base.moves)
    path = RotationPath(f"{base.name}-plateaus", tuple(moves), accel=base.accel, initial=base.initial,
                        initial_dwell=base.initial_dwell, closed=base.closed)
    return path, profile


def _thermal_plateaus(base: Scenario, name: str) -> Scenario:
    path, profile = thermal_plateau_path(base.path)
    return replace(base, name=name, path=path, thermal=thermal_model(), temperature=profile)


def _s16_table1_times(k: int) -> tuple[Scenario, RotationPath]:
    """S16's scenario and its Table 1 path run ``k`` times in a row."""
    one = s16_table1()
    return _s16(), RotationPath(f"s16-table1-x{k}", one.moves * k, accel=one.accel, initial=one.initial,
                                initial_dwell=one.initial_dwell, closed=one.closed)


def _thermal_ramp() -> Scenario:
    base, path = _s16_table1_times(2)
    lo, hi = THERMAL_PLATEAUS_C[0], THERMAL_PLATEAUS_C[-1]
    profile = TemperatureProfile(lo, (Piece("hold", duration_s=600.0),
                                      Piece("ramp", target_c=hi, rate_c_per_min=THERMAL_RAMP_C_PER_MIN)))
    return replace(base, name="thermal-ramp", path=path, thermal=thermal_model(), temperature=profile)


def _thermal_cycle() -> Scenario:
    base, path = _s16_table1_times(4)
    lo, hi = THERMAL_PLATEAUS_C[0], THERMAL_PLATEAUS_C[-1]
    r = THERMAL_RAMP_C_PER_MIN
    profile = TemperatureProfile(lo, (Piece("hold", duration_s=600.0), Piece("ramp", target_c=hi, rate_c_per_min=r),
                                      Piece("hold", duration_s=600.0), Piece("ramp", target_c=lo, rate_c_per_min=r)))
    return replace(base, name="thermal-cycle", path=path, thermal=thermal_model(), temperature=profile)


def _thermal_warmup(duration_s: float = 7200.0) -> Scenario:
    profile = TemperatureProfile(20.0, (Piece("approach", target_c=45.0, tau_s=1200.0, duration_s=duration_s),))
    return replace(_s16(), name="thermal-warmup", path=static(duration_s), thermal=thermal_model(), temperature=profile)


BUILTIN = {
    "s16": lambda d: _s16(),
    "n25": lambda d: _n25(),
    "static": lambda d: _static(d or 3600.0),
    "static-24h": lambda d: _static(d or 86400.0),
    "rotmod16": lambda d: _rotmod(d or 6 * 3600.0),
    "rotmod16-6h": lambda d: _rotmod(d or 6 * 3600.0),
    "n25-rotmod": lambda d: _n25_rotmod(d or 6 * 3600.0),
    "n25-static": lambda d: _n25_static(d or 3600.0),
    "psins19": lambda d: _psins19(),
    "s16-table3": lambda d: _s16_table3(),
    "s16-gimbal": lambda d: _s16_gimbal(),
    "thermal-plateaus": lambda d: _thermal_plateaus(_n25(), "thermal-plateaus"),
    "thermal-plateaus-s16": lambda d: _thermal_plateaus(_s16(), "thermal-plateaus-s16"),
    "thermal-ramp": lambda d: _thermal_ramp(),
    "thermal-cycle": lambda d: _thermal_cycle(),
    "thermal-warmup": lambda d: _thermal_warmup(d or 7200.0),
    "handheld-mems": lambda d: _handheld("mems"),
    "handheld-tactical": lambda d: _handheld("tactical"),
    "handheld-navigation": lambda d: _handheld("navigation"),
    "ferraris-mems": lambda d: _ferraris(),
}
DURATION_SCENARIOS = {"static", "static-24h", "rotmod16", "rotmod16-6h", "n25-rotmod", "n25-static", "thermal-warmup"}


class ScenarioError(ValueError):
    """A scenario that cannot be built."""


def build(name: str, duration_s: float | None = None, rate_hz: float | None = None) -> Scenario:
    """A built-in scenario by name, or a custom one from a ``.toml`` file.

    Parameters
    ----------
    name : str
        A built-in name (``s16``, ``n25``, ``static``, ``rotmod16``, ``handheld-mems``, ... :data:`BUILTIN`)
        or a scenario TOML file.
    duration_s : float, optional
        The duration [s] of the scenarios that take one (:data:`DURATION_SCENARIOS`).
    rate_hz : float, optional
        Another sample rate [Hz].

    Returns
    -------
    Scenario
        The site, the IMU and gimbal errors, the noise, the rotation path and the rate.

    Raises
    ------
    ScenarioError
        An unknown name, a duration that is not positive or for a scenario with a fixed path, a bad
        rate, or a TOML file that does not describe a scenario.

    Examples
    --------
    >>> from inscal.sim.scenarios import build
    >>> sc = build("static", duration_s=600.0, rate_hz=10.0)
    >>> sc.name, sc.n_samples
    ('static', 6000)
    >>> round(float(build("n25").path.segments().t1[-1]), 3)  # the N25 path's length [s]
    2489.0
    """
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
        raise ScenarioError(f"duration must be > 0, got {duration_s} s")
    if name.endswith(".toml") or Path(name).is_file():
        sc = load_toml(name, duration_s)
    elif name in BUILTIN:
        if duration_s is not None and name not in DURATION_SCENARIOS:
            raise ScenarioError(f"scenario {name!r} has a fixed path; --duration-h applies to {sorted(DURATION_SCENARIOS)}")
        sc = BUILTIN[name](duration_s)
    else:
        raise ScenarioError(f"unknown scenario {name!r}; built-in: {', '.join(BUILTIN)}, or a .toml file")
    if rate_hz is not None:
        try:
            sc = replace(sc, rate_hz=float(rate_hz))
        except ValueError as exc:
            raise ScenarioError(str(exc)) from None
    return sc



_TOP_KEYS = {"base", "schema_version", "scenario", "site", "errors", "noise", "path", "thermal", "temperature"}
_TEMPERATURE_KEYS = {"start_c", "pieces", "sensor"}
_PIECE_KEYS = {"kind", "duration_s", "target_c", "rate_c_per_min", "tau_s"}
_SENSOR_KEYS = {"names", "rate_hz", "offsets_c", "noise_c", "quantum_c"}


def load_toml(file, duration_s: float | None = None) -> Scenario:
    p = Path(file)
    d = read_toml(p, ScenarioError, "scenario file")
    nz = d.get("noise")
    if isinstance(nz, dict) and isinstance(nz.get("file"), str) and not Path(nz["file"]).is_absolute():
        nz["file"] = str(p.parent / nz["file"])  # a noise.toml beside the scenario
    try:
        return scenario_from_dict(d, duration_s, default_name=p.stem)
    except (ValueError, PathError, TypeError) as exc:
        raise ScenarioError(f"{p}: {exc}") from None


def gravity_from_field(g) -> GravityModel:
    """``[site] gravity``: "wgs84" | "psins" | {value = 9.79, unit = "m/s^2"(, height_m = h)}
    (a measured value, at the site height unless ``height_m`` says where it was taken)."""
    if isinstance(g, str):
        if g.strip().lower() not in ("wgs84", "psins"):
            raise ScenarioError(f"[site] gravity must be \"wgs84\", \"psins\" or {{value = ..., unit = ...}}, got {g!r}")
        return parse_gravity(g)
    if isinstance(g, dict):
        _check_keys("site.gravity", g, {"value", "unit", "height_m"})
        if "value" not in g or "unit" not in g:
            raise ScenarioError("[site] gravity = {value = ..., unit = ...} needs both value and unit")
        v = units.to_si(float(g["value"]), str(g["unit"]), "accel")
        return GravityModel("measured", float(v), None if "height_m" not in g else float(g["height_m"]))
    raise ScenarioError(f"[site] gravity must be \"wgs84\", \"psins\" or {{value = ..., unit = ...}}, got {g!r}")


def read_noise_file(path) -> NoiseModel:
    """The :class:`~inscal.core.noise_models.NoiseModel` of the noise.toml at ``path`` (a scenario's
    ``[noise] file``); ScenarioError with one line when it cannot be read."""
    try:
        return read_noise(path)[0]
    except NoiseFileError as exc:
        raise ScenarioError(str(exc)) from None


def noise_from_model(model: NoiseModel) -> ImuNoise:
    """The simulator's noise of an identified model (``[noise] file = "noise.toml"``): per axis white
    noise (N), one Gauss-Markov bias (sigma; one correlation time per sensor) and quantization (the
    quantum S = Q sqrt(12) of IEEE 952's Q, one per sensor).  A term the simulator does not draw
    (RW, DR, BI, a second GM) or axes with different correlation times or quanta are refused."""
    kw: dict = {}
    for sensor, names, n_key in (("gyro", ("gx", "gy", "gz"), "arw"), ("accel", ("ax", "ay", "az"), "vrw")):
        try:
            chans = [model.channel(n) for n in names]
        except KeyError as exc:
            raise ScenarioError(f"[noise] file: {exc.args[0]}; the simulator needs {', '.join(names)}") from None
        n, sig, taus, quanta = [], [], set(), set()
        for c in chans:
            codes = [t.code for t in c.terms]
            extra = [k for k in codes if k not in ("QN", "WN", "GM")] + (["second GM"] if codes.count("GM") > 1 else [])
            if extra:
                raise ScenarioError(f"[noise] file: channel {c.name} has {', '.join(extra)}, which the simulator "
                                    "does not draw (it draws QN, WN and one GM per channel)")
            n.append(sum(t.n for t in c.terms if t.code == "WN"))
            sig.append(sum(t.sigma for t in c.terms if t.code == "GM"))
            taus |= {round(t.tc, 9) for t in c.terms if t.code == "GM"}
            quanta.add(round(sum(t.q for t in c.terms if t.code == "QN") * math.sqrt(12.0), 15))
        if len(taus) > 1 or len(quanta) > 1:
            raise ScenarioError(f"[noise] file: the {sensor} axes have different Gauss-Markov correlation times or "
                                "quanta; the simulator takes one per sensor")
        kw[n_key] = np.array(n)
        kw[f"{sensor}_bias_instability"] = np.array(sig)
        if taus:
            kw[f"{sensor}_bias_tau"] = float(taus.pop())
        kw[f"{sensor}_quantization"] = float(quanta.pop())
    return ImuNoise(**kw)


def _check_keys(section: str, d: dict, allowed: set) -> None:
    if not isinstance(d, dict):
        raise ScenarioError(f"[{section}] must be a table")
    unknown = set(d) - allowed
    if unknown:
        raise ScenarioError(f"[{section}]: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}")


def scenario_from_dict(d: dict, duration_s: float | None = None, default_name: str = "custom") -> Scenario:

    _check_keys("top level", d, _TOP_KEYS)
    if "schema_version" in d and d["schema_version"] != SCHEMA_VERSION:
        raise ScenarioError(f"schema_version {d['schema_version']} is not supported (this inscal reads {SCHEMA_VERSION})")
    meta = d.get("scenario", {})
    _check_keys("scenario", meta, {"name", "rate_hz", "duration_h", "duration_s"})
    if "duration_h" in meta and duration_s is None:
        duration_s = float(meta["duration_h"]) * 3600.0
    if "duration_s" in meta and duration_s is None:
        duration_s = float(meta["duration_s"])
    if "base" in d:
        base = build(str(d["base"]), duration_s if str(d["base"]) in DURATION_SCENARIOS else None)
    else:
        base = Scenario(default_name, static(duration_s or 3600.0), N25_SITE)
    name = str(meta.get("name", default_name))
    rate = float(meta.get("rate_hz", base.rate_hz))
    if not (math.isfinite(rate) and rate > 0):
        raise ScenarioError(f"[scenario] rate_hz must be positive, got {rate}")
    site = base.site
    if "site" in d:
        s = d["site"]
        _check_keys("site", s, {"latitude_deg", "longitude_deg", "height_m", "gravity"})
        site = Site(float(s.get("latitude_deg", site.latitude / DEG)) * DEG,
                    float(s.get("longitude_deg", site.longitude / DEG)) * DEG,
                    float(s.get("height_m", site.height)),
                    gravity_from_field(s["gravity"]) if "gravity" in s else site.gravity_model)
    imu, gim = base.imu, base.gimbal
    if "errors" in d:
        merged = errors_to_field(base.imu, base.gimbal)
        merged.update(d["errors"])
        imu, gim = errors_from_field(merged)
    noise = base.noise
    if "noise" in d and isinstance(d["noise"], dict) and "file" in d["noise"]:
        _check_keys("noise", d["noise"], {"file", "encoder_noise"})
        noise = noise_from_model(read_noise_file(d["noise"]["file"]))
        if "encoder_noise" in d["noise"]:
            noise = replace(noise, encoder_noise=noise_from_field({"encoder_noise": d["noise"]["encoder_noise"]}).encoder_noise)
    elif "noise" in d:
        noise = noise_from_field(d["noise"])
    path = base.path
    if "path" in d:
        pd = dict(d["path"])
        if "builtin" in pd:
            bname = pd.pop("builtin")
            if bname not in BUILTIN_PATHS:
                raise ScenarioError(f"[path] unknown builtin {bname!r}; known: {sorted(BUILTIN_PATHS)}")
            if pd:
                raise ScenarioError(f"[path] with builtin takes no other keys, got {sorted(pd)}")
            fn = BUILTIN_PATHS[bname]
            path = fn(duration_s or 3600.0) if bname in ("static", "rotmod16") else fn()
        else:
            path = RotationPath.from_dict(pd)
    elif duration_s is not None and "base" not in d:
        path = static(duration_s)
    if "base" not in d and "path" not in d and duration_s is None:
        # a file with no base, no path and no duration says nothing about the motion: a silent one-hour
        # static record is not what anyone asked for (checked after every table, so their errors come first)
        raise ScenarioError("the scenario names no motion: give a [path] table, base = NAME (a built-in "
                            "scenario), or a duration for a static record ([scenario] duration_h / duration_s)")
    thermal, profile, sensor = _thermal_tables(d, base)
    if base.motion is not None and "path" in d:
        raise ScenarioError("a hand-held base scenario takes no [path] table (its motion is the hand-held session)")
    return Scenario(name, path, site, imu, gim, noise, rate, thermal, profile, sensor, base.motion)


def _thermal_tables(d: dict, base: Scenario) -> tuple[ThermalModel | None, TemperatureProfile | None, TemperatureSensor]:
    """``[thermal]`` and ``[temperature]`` of a scenario file over the base scenario's (module docstring)."""
    thermal, profile, sensor = base.thermal, base.temperature, base.temperature_sensor
    if "thermal" in d:
        td = d["thermal"]
        _check_keys("thermal", td, {"t_ref", "t_min", "t_max", "out_of_range", "sensor", "terms", "fit"})
        # a parameter file's [thermal] pastes as it is: its 1-sigma and [thermal.fit] describe a calibration
        thermal = thermal_from_field({k: v for k, v in td.items() if k != "fit"})[0]
    if "temperature" in d:
        td = d["temperature"]
        _check_keys("temperature", td, _TEMPERATURE_KEYS)
        if "pieces" in td and "start_c" not in td:
            raise ScenarioError("[temperature] pieces need start_c (the temperature at t = 0, degC)")
        if "start_c" in td:
            pieces = td.get("pieces", [])
            if not isinstance(pieces, list):
                raise ScenarioError("[temperature] pieces must be a list of {kind = ..., ...} tables")
            for k, pc in enumerate(pieces):
                _check_keys(f"temperature.pieces[{k}]", pc, _PIECE_KEYS)
                if "kind" not in pc:
                    raise ScenarioError(f"[temperature] pieces[{k}] needs kind (one of {', '.join(PIECE_KINDS)})")
            start = td["start_c"]
            if isinstance(start, bool) or not isinstance(start, (int, float)):
                raise ScenarioError(f"[temperature] start_c must be a number of degC, got {start!r}")
            try:
                profile = TemperatureProfile(float(start), tuple(Piece(**pc) for pc in pieces))
            except ValueError as exc:
                raise ScenarioError(f"[temperature] {exc}") from None
        if "sensor" in td:
            sd = td["sensor"]
            _check_keys("temperature.sensor", sd, _SENSOR_KEYS)
            kw = {k: sd[k] for k in _SENSOR_KEYS if k in sd}
            if "names" in kw:
                if not (isinstance(kw["names"], list) and kw["names"] and all(isinstance(x, str) for x in kw["names"])):
                    raise ScenarioError(f"[temperature.sensor] names must be a list of names, got {kw['names']!r}")
                kw.setdefault("offsets_c", [])  # new names: offsets zero unless given
            for key in ("rate_hz", "noise_c", "quantum_c"):
                v = kw.get(key, 0.0)
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ScenarioError(f"[temperature.sensor] {key} must be a number, got {v!r}")
            offs = kw.get("offsets_c", [])
            if not (isinstance(offs, list) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in offs)):
                raise ScenarioError(f"[temperature.sensor] offsets_c must be a list of degC, got {offs!r}")
            try:
                sensor = replace(sensor, **{k: (tuple(v) if isinstance(v, list) else float(v)) for k, v in kw.items()})
            except ValueError as exc:
                raise ScenarioError(f"[temperature.sensor] {exc}") from None
    if thermal is not None and not thermal.is_zero and profile is None:
        raise ScenarioError("[thermal] needs a temperature profile: a [temperature] table with start_c and pieces "
                            "(or a base scenario that has one)")
    if thermal is not None and thermal.sensor and thermal.sensor not in sensor.names:
        raise ScenarioError(f"[thermal] sensor {thermal.sensor!r} is not one of the recorded temperature sensors "
                            f"({', '.join(sensor.names)}; [temperature.sensor] names)")
    return thermal, profile, sensor


# ---------------------------------------------------------------------------- s16-table2
#: S16 Table 2 "after filter" figures (field units of :data:`inscal.core.error_model.PARAMETERS`)
S16_TABLE2 = {"gyro_g_sensitivity": 0.0002, "accel_nonlinearity": 1.3, "accel_cross_coupling": 1.5,
              "accel_lever_arm": 0.01}
