"""Maps the reference generator's output (:mod:`tests.oracles.reference_imu`, PSINS conventions) to
inscal: its record-like object, an HDF5 record file, and inscal's canonical truth.

Error model map (PSINS -> inscal canonical, :mod:`inscal.core.error_model`)
--------------------------------------------------------------------------
PSINS:  ``w_meas = Kg w + eb + Gs f``,  ``f_meas = Ka f' + Ka2 f'^2 + db``.
inscal: ``N_g = M_g (w + G f) + eps``,  ``N_a = M_a (f + a_size + K2 f^2 + Kx f^x) + nabla``,
``M = (I + K)(I + E)``.

* ``M_g = Kg`` (split exactly into K, E by :func:`inscal.core.error_model.split_scale_misalignment`),
  ``G = Kg^-1 Gs`` (exact), ``eps = eb``.
* ``M_a = Ka``, ``nabla = db``; the lever arm rows are the accelerometer positions in both
  (``a_size_i = e_i . (w x (w x p_i) + w_dot x p_i)``): copied as they are.
* ``Ka2``: ``Ka f + Ka2 f^2 = Ka (f + Ka^-1 diag(Ka2) f^2)``.  inscal's K2 is diagonal, so
  ``K2 = diag(Ka^-1) * Ka2`` (the diagonal of ``Ka^-1 diag(Ka2)``, exact on it) and the
  off-diagonal part ``(Ka^-1)_ij Ka2_j f_j^2`` (i > j, Ka lower triangular) is dropped: first order,
  of size ``|dKa_ij| |Ka2_j| g^2`` (1e-4 x 50 ug/g^2 = 0.005 ug at most for :func:`psins_truth`);
  :func:`k2_dropped_bound` gives it for a given set.
* Time asynchrony: inscal's ``time_asynchrony`` is the accelerometer LAG (accelerometer windows
  ``[t_{k-1} - tau, t_k - tau]``).  The delay mode is exactly that: ``time_asynchrony = +tau``.  The
  PSINS form ``f - tau w x f`` is the first-order expansion of ``f^b(t + tau)`` (accelerometers
  sampled tau EARLY): ``time_asynchrony = -tau``, leaving ``-tau (C_n^b w_ie^n) x f^b`` (PSINS
  uses ``w_ib`` where the kinematics have ``w_nb``: ~0.06 ug for 1 ms) and O(tau^2) unmapped.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

# a plain module next to this one: tests/ has no packages, this folder is on sys.path (conftest.py)
from reference_imu import ImuRecord, PsinsErrors

from inscal.core.earth import Site, parse_gravity
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise, split_scale_misalignment
from inscal.io.recordfile import write_record
from inscal.io.records import Record, Truth


def inscal_site(gen: ImuRecord) -> Site:
    """inscal's Site with the generator's gravity model (``wgs84``/``psins``, or a measured value).
    The generator's ``psins-legacy`` formula has no inscal model: it becomes a measured value."""
    gm = gen.gravity_model
    model = parse_gravity(gen.gravity if (not isinstance(gm, str) or gm == "psins-legacy") else gm)
    return Site(latitude=gen.lat, longitude=gen.lon, height=gen.height, gravity_model=model)


def to_record(gen: ImuRecord) -> SimpleNamespace:
    """The record-like object inscal's estimators take (as tests/conftest.py ``as_record``):
    time, dtheta, dvel, rate_hz, site; no gimbal angles, no path."""
    return SimpleNamespace(time=gen.time, dtheta=gen.dtheta, dvel=gen.dvel, gimbal=None, rate_hz=gen.rate_hz,
                           site=inscal_site(gen), path=None)


def to_inscal_truth(gen_or_errors: ImuRecord | PsinsErrors) -> ImuErrors:
    """inscal's canonical :class:`ImuErrors` of a PSINS error set (see the module docstring)."""
    e = gen_or_errors.truth if isinstance(gen_or_errors, ImuRecord) else gen_or_errors
    kg, eg = split_scale_misalignment(e.Kg)
    ka, ea = split_scale_misalignment(e.Ka)
    Ka_inv = np.linalg.inv(e.Ka)
    tau = e.tau if e.asynchrony == "delay" else -e.tau
    return ImuErrors(
        gyro_scale_factor=kg, gyro_misalignment=eg, gyro_bias=e.eb,
        gyro_g_sensitivity=np.linalg.solve(e.Kg, e.Gs),
        accel_scale_factor=ka, accel_misalignment=ea, accel_bias=e.db,
        accel_nonlinearity=np.diag(Ka_inv) * e.Ka2,
        accel_lever_arm=e.lever, time_asynchrony=tau,
    )


def k2_dropped_bound(errors: PsinsErrors, g: float) -> float:
    """Largest specific force [m/s^2] the K2 map drops: ``max_i sum_j!=i |(Ka^-1)_ij Ka2_j| g^2``."""
    N = np.linalg.inv(errors.Ka) * errors.Ka2[None, :]
    np.fill_diagonal(N, 0.0)
    return float(np.max(np.sum(np.abs(N), axis=1))) * g * g


def to_inscal_record(gen: ImuRecord, scenario: str = "reference-imu") -> Record:
    """An :class:`inscal.io.records.Record` with the mapped truth (no gimbal angles, no path)."""
    noise = ImuNoise(arw=gen.arw, vrw=gen.vrw)
    return Record(time=np.asarray(gen.time, float), dtheta=np.asarray(gen.dtheta, float),
                  dvel=np.asarray(gen.dvel, float), gimbal=None, rate_hz=gen.rate_hz, site=inscal_site(gen),
                  path=None, truth=Truth(to_inscal_truth(gen), GimbalErrors(), noise), scenario=scenario,
                  source="tests/oracles/reference_imu.py")


def write_inscal_record(path, gen: ImuRecord, overwrite: bool = False) -> Record:
    """Write the generated record as a real inscal HDF5 record file (for CLI tests); returns it."""
    rec = to_inscal_record(gen)
    write_record(path, rec, overwrite=overwrite)
    return rec
