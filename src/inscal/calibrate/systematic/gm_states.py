"""Gauss-Markov bias states of the systematic filter, from an identified noise model
(:class:`inscal.core.noise_models.NoiseModel`, e.g. a ``noise.toml`` of ``inscal noise``).

Model.  Each Gauss-Markov (GM) term of a gyro or accelerometer channel is a first-order Gauss-Markov bias
``b'(t) = -b / tc + w``, stationary std ``sigma``, added to that sensor axis's constant bias (Maybeck, Stochastic
Models, Estimation and Control, vol. 1, sec. 4.11; Gelb, Applied Optimal Estimation, Table 3.8-1).  Its error
state ``x = b_est - b_true`` enters the rate and specific-force errors exactly as the constant bias's does (S16
eq. 18-19: ``dw = ... - db_g``, ``df = ... - db_a``), so its column in the navigation rows of ``Phi`` is the bias
column.  Over a filter step ``T`` (scaled states, :mod:`inscal.calibrate.systematic.kernel`)::

    Phi_gm,gm  = exp(-T / tc)                                   (exact: the AR(1) of GaussMarkov.phi)
    Qd_gm,gm   = sigma^2 (1 - exp(-2 T / tc))                   (exact: the AR(1) innovation variance)
    Phi_nav,gm = Phi_np[:, bias column] exp(-T / (2 tc))        (int_0^T e^{F (T-t)} F_b(t) e^{-t/tc} dt: exact
                                                                 to O((T/tc)^2) in the attitude rows, T/(6 tc)
                                                                 off in the velocity rows, which weight the
                                                                 step's start more: 2e-4 at T = 1 s, tc = 600 s)
    Qd_nav,gm  = Qd_gm,gm v / 2,  Qd_nav,nav += Qd_gm,gm v v^T / 3   (v = the bias column: the response within
                                                                 the step to noise entering it, to first order)

The state vector is ``[navigation (9) | GM (n_gm) | parameters]``: the GM states are dynamic like the navigation,
so the square-root prediction (:func:`inscal.core.kalman.sr_predict` with ``n = 9 + n_gm``) and the
Bryson-Frazier smoother move them and keep the parameters constant.  The closed loop feeds the GM estimate back
like every other state, into an estimate the compensation subtracts from each sensor axis (beside the constant
bias), decayed by ``exp(-dt / tc)`` sample by sample (the AR(1) mean; ``exp(-T / tc)`` over a step), so that the
error ``x`` follows the model between updates and its column is the bias column weighted by ``exp(-t / tc)``.  Each pass
starts the GM estimates at zero with their stationary prior ``sigma``.

The white terms (WN) of the model are the filter's white noise (``--arw``/``--vrw``).  Bias instability (BI,
flicker), rate random walk and ramp terms are not states: a model with them and no GM term adds no state (a
note says so).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numba import njit

from inscal.calibrate.systematic.states import N_NAV, GMState, StateSet
from inscal.calibrate.windows import CalibrationError
from inscal.core.noise_models import GaussMarkov, NoiseModel, WhiteNoise

#: the channel names of a six-axis noise model: gyros, then accelerometers
GYRO_NAMES = ("gx", "gy", "gz")
ACCEL_NAMES = ("ax", "ay", "az")


def _channels(model: NoiseModel, names) -> list:
    try:
        return [model.channel(n) for n in names]
    except KeyError as exc:
        raise CalibrationError(f"noise model: {exc.args[0]}; calibration needs channels "
                               f"{', '.join(GYRO_NAMES + ACCEL_NAMES)}") from None


def white_noise(model: NoiseModel) -> tuple[np.ndarray, np.ndarray]:
    """The white-noise densities (ARW [rad/sqrt(s)], VRW [m/s/sqrt(s)]) per axis of a six-axis model: the sum of
    each channel's WN terms; CalibrationError (one line) where a channel has none."""
    out = []
    for names in (GYRO_NAMES, ACCEL_NAMES):
        v = []
        for c in _channels(model, names):
            n2 = sum(t.n ** 2 for t in c.terms if isinstance(t, WhiteNoise))
            if not n2 > 0:
                raise CalibrationError(f"noise model: channel {c.name} has no white-noise (WN) term; the filter needs "
                                       "one per channel")
            v.append(math.sqrt(n2))
        out.append(np.array(v))
    return out[0], out[1]


def gm_states(model: NoiseModel) -> tuple[GMState, ...]:
    """One :class:`GMState` per Gauss-Markov term of the six channels (gyros first, then accelerometers)."""
    out = []
    for sensor, names in (("gyro", GYRO_NAMES), ("accel", ACCEL_NAMES)):
        for i, c in enumerate(_channels(model, names)):
            out += [GMState(sensor, i, float(t.sigma), float(t.tc)) for t in c.terms
                    if isinstance(t, GaussMarkov) and t.sigma > 0]
    return tuple(out)


def unmodelled_terms(model: NoiseModel) -> list[str]:
    """The terms of the six channels that the filter neither weights (WN) nor carries as states (GM):
    ``["gx: BI", ...]``."""
    out = []
    for c in _channels(model, GYRO_NAMES + ACCEL_NAMES):
        out += [f"{c.name}: {t.code}" for t in c.terms if not isinstance(t, (WhiteNoise, GaussMarkov))
                and t.code != "QN"]
    return out


def gm_step_arrays(st: StateSet, sig: np.ndarray, T: float) -> dict:
    """The per-pass constants of the GM states for a step ``T`` [s] and the state scaling ``sig`` (N,): the
    sensor (0 gyro, 1 accel) and axis of each, the parameter column of its axis's constant bias, ``phi =
    exp(-T/tc)``, ``mid = exp(-T/(2 tc))`` times ``sig_gm / sig_bias`` (the scaled column factor), the scaled
    discrete noise ``sigma^2 (1 - phi^2) / sig_gm^2`` and the parameter part of the scaling (``sig[:9]`` and
    ``sig[n_dyn:]``: what the parameter columns and the feedback index as ``9 + c``)."""
    n = len(st.gm)
    nd = st.n_dyn
    off = st.offsets()
    sensor = np.array([0 if g.sensor == "gyro" else 1 for g in st.gm], np.int64)
    axis = np.array([g.axis for g in st.gm], np.int64)
    col = np.array([off["gyro_bias" if g.sensor == "gyro" else "accel_bias"] - nd + g.axis for g in st.gm], np.int64)
    phi = np.array([math.exp(-T / g.tc) for g in st.gm])
    sg = sig[N_NAV:nd]
    scale = np.array([math.exp(-T / (2.0 * g.tc)) for g in st.gm]) * sg / sig[nd + col] if n else np.empty(0)
    q = np.array([g.sigma ** 2 * -math.expm1(-2.0 * T / g.tc) for g in st.gm]) / sg ** 2 if n else np.empty(0)
    sigp = np.concatenate([sig[:N_NAV], sig[nd:]])
    return {"sensor": sensor, "axis": axis, "col": col, "phi": phi, "scale": scale, "q": q, "sigp": sigp}


@njit(cache=True)
def assemble(phinn9, Qd9, phinp9, col, phi, scale, q, phinn, phinp, Qd):
    """The step's scaled ``Phi_nn`` (nd, nd), ``Phi_np`` (nd, npar) and ``Qd`` (nd, nd) with the GM states
    (module docstring) from the navigation's ``phinn9``, ``Qd9`` (9, 9) and ``phinp9`` (9, npar)."""
    nd = phinn.shape[0]
    ng = nd - 9
    npar = phinp.shape[1]
    for i in range(nd):
        for j in range(nd):
            phinn[i, j] = 0.0
            Qd[i, j] = 0.0
        for j in range(npar):
            phinp[i, j] = phinp9[i, j] if i < 9 else 0.0
    for i in range(9):
        for j in range(9):
            phinn[i, j] = phinn9[i, j]
            Qd[i, j] = Qd9[i, j]
    for g in range(ng):
        c = col[g]
        phinn[9 + g, 9 + g] = phi[g]
        Qd[9 + g, 9 + g] = q[g]
        for i in range(9):
            v = phinp9[i, c] * scale[g]
            phinn[i, 9 + g] = v
            Qd[i, 9 + g] = 0.5 * q[g] * v
            Qd[9 + g, i] = 0.5 * q[g] * v
            for j in range(9):
                Qd[i, j] += q[g] * v * phinp9[j, c] * scale[g] / 3.0


@njit(cache=True)
def effective_biases(bg, ba, gmx, sensor, axis, bgu, bau):
    """The biases the compensation subtracts: the constant ``bg``, ``ba`` plus the GM estimates ``gmx`` of each
    axis (``bgu``, ``bau``, in place; equal to ``bg``, ``ba`` without GM states)."""
    for i in range(3):
        bgu[i] = bg[i]
        bau[i] = ba[i]
    for g in range(gmx.shape[0]):
        if sensor[g] == 0:
            bgu[axis[g]] += gmx[g]
        else:
            bau[axis[g]] += gmx[g]


def noise_setup(model: NoiseModel, arw, vrw, st: StateSet) -> tuple:
    """The filter's noise from an identified model: ``(arw, vrw, states, note)``, the white noise of its WN terms
    where ``arw``/``vrw`` are None, the state set with a GM state per Gauss-Markov term, and a note naming the terms
    the filter does not carry (None when there are none)."""
    if not isinstance(model, NoiseModel):
        raise CalibrationError(f"noise model: expected a NoiseModel, got {type(model).__name__}")
    a, v = white_noise(model)
    gm = gm_states(model)
    if gm and st.thermal:
        raise CalibrationError("Gauss-Markov bias states and thermal states cannot be combined (the thermal model "
                               "acts on the constant bias); calibrate without --noise or without thermal states")
    extra = unmodelled_terms(model)
    note = None
    if extra:
        note = (f"noise model: {', '.join(extra)} not carried by the filter (white noise and Gauss-Markov terms only): "
                "their error is not in the sigma")
    return (a if arw is None else arw), (v if vrw is None else vrw), replace(st, gm=gm), note
