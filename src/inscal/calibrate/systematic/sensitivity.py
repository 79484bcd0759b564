"""What the systematic filter cannot check: the site latitude and the record's time scale, and how far each may
be off before the reported parameters move by their own sigma.

A wrong latitude and a wrong sample rate fit the innovations almost as well as the right ones (they alias into
biases, scale factors and g-sensitivities), so the fit's chi-square cannot reveal them; the user must know them
to the accuracy the reported sigma assume.  Both act on the navigation of a static site as known forcings of
the error dynamics (package docstring, S16 eq. 17):

* latitude off by ``dL`` (the value used minus the truth): the navigator removes the Earth rate and gravity of
  the wrong latitude, so ``phi' += -d w_ie^n = -W_ie [0, -sin L, cos L] dL`` and ``dv_U' += -(dg/dL) dL``;
* time scale off by ``e`` (true sample interval / stated - 1): the increments are integrals over the true
  interval and the navigator integrates the Earth rate and gravity over the stated one, so
  ``phi' += e w_ie^n`` and ``dv_U' += e g`` (the rotation and the sensed force themselves stay right).

The forcing ``b`` of one step enters as ``u = (I + Phi_nn) / 2 b T`` (the step's mean transition); the estimation
error of the closed-loop filter then obeys ``e-_k = Phi_k e+_(k-1) + u_k``, ``e+_k = (I - K_k H) e-_k`` with the
pass's stored gains and transitions, and the parameter part of ``e+_M`` is the shift of the final estimate (the feedback removes ``-e``), carried
through the driver's change of prior and into the canonical parameters.  ``tests/calibrate/test_robust_scheme.py``
checks the prediction against re-runs with the latitude and the rate changed.
"""

from __future__ import annotations

import math

import numpy as np

from inscal.core.earth import OMEGA_IE

#: states of the measurement rows (velocity, position) in the filter's order
IDX_MEAS = np.arange(3, 9)


def forcings(lat: float, g: float, dg_dlat: float) -> np.ndarray:
    """(9, 2) physical forcing per unit input of the navigation error rates ``[phi, dv, dp]`` (ENU): column 0 a
    latitude error of 1 rad, column 1 a time-scale error of 1 (module docstring)."""
    b = np.zeros((9, 2))
    b[0:3, 0] = -OMEGA_IE * np.array([0.0, -math.sin(lat), math.cos(lat)])
    b[5, 0] = -dg_dlat
    b[0:3, 1] = OMEGA_IE * np.array([0.0, math.cos(lat), math.sin(lat)])
    b[5, 1] = g
    return b


def parameter_shift(K_st: np.ndarray, phinn_st: np.ndarray, phinp_st: np.ndarray, steps: int, sig: np.ndarray,
                    b: np.ndarray, T: float) -> np.ndarray:
    """The shift of the pass's final parameter estimate (physical, (npar, k)) for the forcings ``b`` (9, k) per
    unit input, from the pass's stored gains ``K_st`` (M, N, 6), ``Phi_nn`` (M, 9, 9) and ``Phi_np`` (M, 9,
    npar), all in the scaled states (``sig`` (N,): the filter works on ``x / sig``)."""
    N = sig.shape[0]
    nd = phinn_st.shape[1]  # dynamic states (navigation, and Gauss-Markov biases when there are some)
    k = b.shape[1]
    e = np.zeros((N, k))
    bd = np.zeros((nd, k))
    bd[:9] = b
    for s in range(steps):
        phinn = phinn_st[s]
        u = 0.5 * (np.eye(nd) + phinn) @ bd * T / sig[:nd, None]
        nav = phinn @ e[:nd] + phinp_st[s] @ e[nd:] + u
        e[:nd] = nav
        e -= K_st[s] @ e[IDX_MEAS]
    return e[nd:] * sig[nd:, None]  # the feedback removes the estimated error: the parameters move by +e


def tolerances(shift_canonical: np.ndarray, sigma: np.ndarray) -> tuple[float, float, int, int]:
    """``(latitude [rad], time scale [1])``: how far each input may be off before the largest shift of a
    canonical parameter reaches its sigma, and the index of that parameter for each (``shift_canonical``
    (n, 2) per unit input, ``sigma`` (n,), NaN for fixed components)."""
    ok = np.isfinite(sigma) & (sigma > 0)
    out = []
    for c in range(2):
        ratio = np.where(ok, np.abs(shift_canonical[:, c]) / np.where(ok, sigma, 1.0), 0.0)
        i = int(np.argmax(ratio))
        out.append((1.0 / ratio[i] if ratio[i] > 0 else math.inf, i))
    return out[0][0], out[1][0], out[0][1], out[1][1]
