"""The systematic filter's smoothed covariances: positive definite at every stored step?

Runs ``calibrate(rec, "systematic51", keep_passes=True)`` on a noisy record (default: the built-in ``s16``
record, 1.07 h at 100 Hz, and the ``psins19`` path) and, at every stored step of the last pass and at the
start, checks the smoothed covariance (scaled states) of

* the square-root information smoother the package runs (:func:`inscal.core.kalman.sr_smoothed` of the
  backward square-root information and the forward predicted covariance), and
* the modified Bryson-Frazier form it replaced (``Pm - Pm Lam Pm`` with the constants' split,
  :func:`inscal.core.kalman.smoothed_constant`), replayed here on the same stores (compiled, no navigation),

printing per form: the steps whose Cholesky factorisation fails, the negative diagonal entries, and the smallest
eigenvalue against the largest, of the covariance and of its correlation matrix.  Then where the MBF form is
sound (its Cholesky succeeds) the largest relative difference of the two forms' sigma (navigation states,
constants), their smoothed estimates' largest difference in units of sigma, and both smoothers' times.

    .venv/bin/python bench/smoother_positivity.py                   # s16 and psins19
    .venv/bin/python bench/smoother_positivity.py --scenario s16 --passes 1
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from types import SimpleNamespace

import numpy as np
from numba import njit

from inscal.calibrate import calibrate
from inscal.calibrate.systematic.kernel import smooth_pass
from inscal.calibrate.systematic.smoother import add_feedback, stored_before
from inscal.calibrate.systematic.states import IDX_MEAS
from inscal.core import kalman as filters
from inscal.sim import scenarios
from inscal.sim.simulate import simulate


@njit(cache=True)
def mbf_replay(P0, K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm, hist_x, hist_P, Ppp):
    """The MBF covariance smoother as the package ran it before the square-root form (no encoder rows)."""
    N = P0.shape[0]
    nd = phinn_st.shape[1]
    lam = np.zeros(N)
    Lam = np.zeros((N, N))
    rem = np.zeros(N - nd)
    ih = stored_before(M, M, hist_every) - 1
    for k in range(M - 1, -1, -1):
        filters.smoother_step(lam, Lam, IDX_MEAS, K_st[k], Si_st[k], sz_st[k])
        add_feedback(rem, K_st[k], Si_st[k], sz_st[k], nd)
        if k % hist_every == 0 or k == M - 1:
            x, Ps = filters.smoothed_constant(hist_Pm[ih], lam, Lam, nd, rem, Ppp)
            hist_x[ih] = x
            hist_P[ih] = Ps
            ih -= 1
        filters.adjoint_back(lam, Lam, nd, phinn_st[k], phinp_st[k])
    return filters.smoothed_constant(P0, lam, Lam, nd, rem, Ppp)


def positivity(Ps: np.ndarray) -> dict:
    """Cholesky failures, negative diagonals and min/max eigenvalue ratios over a stack of covariances."""
    fails, negdiag, ratio, ratio_c, first_fail = 0, 0, np.inf, np.inf, None
    for i, P in enumerate(Ps):
        d = np.diag(P)
        negdiag += int(np.sum(d <= 0))
        try:
            np.linalg.cholesky(P)
        except np.linalg.LinAlgError:
            fails += 1
            first_fail = i if first_fail is None else first_fail
        w = np.linalg.eigvalsh(P)
        ratio = min(ratio, w[0] / w[-1])
        if np.all(d > 0):
            s = 1.0 / np.sqrt(d)
            wc = np.linalg.eigvalsh(P * np.outer(s, s))
            ratio_c = min(ratio_c, wc[0] / wc[-1])
        else:
            ratio_c = -np.inf
    return {"fails": fails, "negdiag": negdiag, "ratio": ratio, "ratio_corr": ratio_c, "first_fail": first_fail}


def study(name: str, passes: int | None, seed: int) -> None:
    sc = scenarios.build(name)
    rec = simulate(sc, np.random.default_rng(seed)).to_record()
    kw = {"max_passes": passes} if passes else {}
    res = calibrate(SimpleNamespace(dtheta=rec.dtheta, dvel=rec.dvel, rate_hz=rec.rate_hz, site=rec.site),
                    "systematic51", keep_passes=True, **kw)
    out = res.pass_output
    sm = out.smoother
    nd = sm.phinn_st.shape[1]
    N = sm.K_st.shape[1]
    assert not np.any(sm.att_used), "encoder rows: not replayed here"
    # the square-root smoother (again, timed) and the MBF replay on the same stores
    new = dataclasses.replace(out) if dataclasses.is_dataclass(out) else out
    t_new = min(_timed(lambda: smooth_pass(new)) for _ in range(3))
    hist_x_old = np.empty_like(out.hist_x)
    hist_P_old = np.empty_like(out.hist_P)
    args = (np.eye(N), sm.K_st, sm.Si_st, sm.sz_st, sm.phinn_st, sm.phinp_st, sm.hist_every, out.steps, out.hist_Pm,
            hist_x_old, hist_P_old, np.ascontiguousarray(out.Pf[nd:, nd:]))
    mbf_replay(*args)
    t_old = min(_timed(lambda: mbf_replay(*args)) for _ in range(3))
    x0_old, P0_old = mbf_replay(*args)
    print(f"\n{name}: {rec.duration / 3600:.2f} h at {rec.rate_hz:g} Hz, {out.steps} filter steps, {N} states, "
          f"{out.hist_P.shape[0]} stored steps and the start, pass {res.diagnostics.get('passes', '?')}")
    for label, Ps in (("square-root information (now)", np.concatenate([out.P0s[None], out.hist_P])),
                      ("MBF Pm - Pm Lam Pm, split (before)", np.concatenate([P0_old[None], hist_P_old]))):
        p = positivity(Ps)
        where = "" if p["first_fail"] is None else f" (first: {'the start' if p['first_fail'] == 0 else 'stored step ' + str(p['first_fail'] - 1)})"
        print(f"  {label:36s} Cholesky fails {p['fails']:4d}{where}, diagonal <= 0: {p['negdiag']}, "
              f"min lambda_min/lambda_max {p['ratio']:.3g}, of the correlation matrix {p['ratio_corr']:.3g}")
        if p["first_fail"] is None:
            continue
        i = p["first_fail"]
        w = np.linalg.eigvalsh(Ps[i])
        print(f"    {'':34s} at that step: eigenvalues {w[0]:.3g} .. {w[-1]:.3g}, diagonal min {np.min(np.diag(Ps[i])):.3g}")
    # agreement where the MBF form is sound
    sound = []
    for i, P in enumerate(hist_P_old):
        try:
            np.linalg.cholesky(P)
            sound.append(i)
        except np.linalg.LinAlgError:
            pass
    sound = np.array(sound)
    s_new = np.sqrt(np.diagonal(out.hist_P, axis1=1, axis2=2)[sound])
    s_old = np.sqrt(np.diagonal(hist_P_old, axis1=1, axis2=2)[sound])
    rel = np.abs(s_new / s_old - 1.0)
    dx = np.max(np.abs(out.hist_x - hist_x_old) / np.sqrt(np.abs(np.diagonal(out.hist_P, axis1=1, axis2=2))))
    j = np.unravel_index(np.argmax(rel[:, :nd]), rel[:, :nd].shape)
    print(f"  where the MBF form is sound ({sound.size} of {hist_P_old.shape[0]} stored steps): sigma relative difference "
          f"navigation max {np.max(rel[:, :nd]):.3g} (stored step {sound[j[0]]}, state {j[1]}), median "
          f"{np.median(rel[:, :nd]):.3g}; constants max {np.max(rel[:, nd:]):.3g}; navigation max from stored step 1 "
          f"on {np.max(rel[sound >= 1, :nd]):.3g}, from step 10 on {np.max(rel[sound >= 10, :nd]):.3g}")
    pf = np.diag(out.Pf)[nd:]
    print(f"  constants' smoothed variance vs the final filtered: max relative difference "
          f"{np.max(np.abs(np.diagonal(out.hist_P, axis1=1, axis2=2)[:, nd:] / pf - 1.0)):.3g}")
    print(f"  smoothed estimates: largest |difference| / sigma {dx:.3g}")
    print(f"  covariance smoother time: square-root {t_new:.3f} s, MBF {t_old:.3f} s (ratio {t_new / t_old:.2f})")


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", action="append", default=None, help="built-in scenario (repeatable; default s16, "
                    "psins19)")
    ap.add_argument("--passes", type=int, default=None, help="max_passes (default: the driver's)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    for name in args.scenario or ["s16", "psins19"]:
        study(name, args.passes, args.seed)


if __name__ == "__main__":
    main()
