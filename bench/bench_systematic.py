"""Benchmark: the S16 systematic 51-state calibration of the built-in ``s16`` record
(1.07 h at 100 Hz, 386,100 samples, 3,861 filter steps of 1 s), after compilation.

Times, in this process (best of ``--repeats``):

(a) one full ``calibrate(rec, "systematic51")``: every pass (navigation, filter, smoother)
    plus the driver's own work (noise estimate, resolution, coarse alignment, Jacobian, history,
    fit), each phase timed apart;
(b) one single pass (``max_passes=1``), and inside it the pass kernel (compensation,
    navigation, Jacobian accumulation, discretisation, predict and update) and the smoother;
(c) the same single-pass filter and smoother written densely with filterpy
    (``KalmanFilter(dim_x=51, dim_z=6)``, ``rts_smoother``) on the SAME per-step 51x51 Phi
    (built from the pass's ``Phi_nn``, ``Phi_np``), the SAME Q (the pass kernel's third-order
    Van Loan ``Q_d``, rebuilt from each step's ``Phi_nn``), R and scaled measurements; the
    navigation is NOT part of (c).  The structured engine (``inscal.core.kalman``) is timed on the
    same inputs (a replay of predict/update and of the MBF smoother without the navigation),
    and the ratio (c) / engine is reported, with the conservative ratio (c) / whole pass;
(d) peak memory of a fresh subprocess that runs one full calibration (its high-water mark
    VmHWM, reset before the run to separate the run from the imports and the warm-up), and the
    tracemalloc peak of that calibration (the arrays the driver and the filter allocate).

It also checks that the dense filterpy filter gives our numbers: the filtered covariance
diagonal and estimate after the last update, and the smoothed states and covariance
diagonals at every stored step (scaled states), and prints where the time of (a) goes.

Run: ``python bench/bench_systematic.py [--repeats N] [--no-memory] [--no-filterpy] [--e2e]`` (``--e2e``: (a) and
(d) only).  Every time is printed as ``in X s``, the form ``bench/compare.py`` reads
(``python bench/compare.py --base REV --same-script bench_systematic.py --args=--e2e``).
Targets: (a) under 3 s on a 2-core machine, goal 1 s; (c) / filter+smoother >= 10x;
peak memory under 500 MB.
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from types import SimpleNamespace

import numpy as np
from numba import njit

from inscal.core import kalman as filters
from inscal.sim import scenarios, simulate
from inscal.calibrate import calibrate
from inscal.calibrate.systematic.dynamics import nav_F
from inscal.calibrate.systematic.jacobian import discretise
from inscal.calibrate.systematic import driver as DRIVER
from inscal.calibrate.systematic import kernel as KERNEL
from inscal.calibrate.systematic.kernel import _pass_kernel, run_pass
from inscal.calibrate.systematic.smoother import add_feedback
from inscal.calibrate.systematic.states import IDX_MEAS

TARGET_S, GOAL_S, TARGET_RATIO, TARGET_MB = 3.0, 1.0, 10.0, 500.0
#: the timed functions, each patched in the module that looks it up when it is called (absent ones skipped)
TIMED = ((DRIVER, "run_pass"), (KERNEL, "_pass_kernel"), (KERNEL, "smooth_vector_kernel"), (KERNEL, "smooth_kernel"),
         (DRIVER, "smooth_pass"), (DRIVER, "pass_history"), (DRIVER, "canonical_jacobian"),
         (DRIVER, "estimate_white_noise"), (DRIVER, "data_resolution"), (DRIVER, "float32_rounding"),
         (DRIVER, "_first_motion"), (DRIVER, "coarse_align"), (DRIVER, "misfit_signature"))
#: the driver's own phases of (a): (label, timed functions)
PHASES = (("noise estimate (second differences)", ("estimate_white_noise",)),
          ("quantum and float32 rounding of the record", ("data_resolution", "float32_rounding")),
          ("first motion and coarse alignment", ("_first_motion", "coarse_align")),
          ("smoother run by the driver (smooth_pass)", ("smooth_pass",)),
          ("canonical Jacobian", ("canonical_jacobian",)),
          ("history (pass_history)", ("pass_history",)),
          ("misfit signature of the fit", ("misfit_signature",)))


# ----------------------------------------------------------------------------- helpers
def _record(rng_seed: int = 1):
    sc = scenarios.build("s16")
    d = simulate.simulate(sc, np.random.default_rng(rng_seed))
    return sc, SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=sc.rate_hz, site=sc.site)


def _slice(rec, n):
    return SimpleNamespace(dtheta=rec.dtheta[:n], dvel=rec.dvel[:n], rate_hz=rec.rate_hz, site=rec.site)


def _copy(v):
    """A copy of an argument: arrays, and the kernel's named tuples of arrays, field by field."""
    if isinstance(v, np.ndarray):
        return np.copy(v)
    if isinstance(v, tuple) and hasattr(v, "_fields"):
        return type(v)(*[_copy(x) for x in v])
    return v


@contextlib.contextmanager
def _timers(acc: dict, keep: dict | None = None):
    """Wrap the driver's kernels (module globals of inscal.calibrate.systematic.driver and .kernel)
    with timers; ``keep`` receives copies of the first arguments of run_pass and _pass_kernel."""
    orig = {(m, n): getattr(m, n) for m, n in TIMED if hasattr(m, n)}

    def wrap(name, f):
        def g(*a, **k):
            if keep is not None and name in ("run_pass", "_pass_kernel") and name not in keep:
                keep[name] = ([_copy(v) for v in a], dict(k))
            t0 = time.perf_counter()
            r = f(*a, **k)
            acc[name] = acc.get(name, 0.0) + time.perf_counter() - t0
            acc[name + "#"] = acc.get(name + "#", 0) + 1
            return r
        return g

    for (m, n), f in orig.items():
        setattr(m, n, wrap(n, f))
    try:
        yield acc
    finally:
        for (m, n), f in orig.items():
            setattr(m, n, f)


def _best(fn, repeats: int):
    best, out = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = fn()
        el = time.perf_counter() - t0
        if el < best:
            best, out = el, r
    return best, out


# ----------------------------------------------------------------------------- the structured engine, replayed
@njit(cache=True)
def _engine_forward(P, phinn_st, phinp_st, Qd_st, rs, zs, hist_every, K_st, Si_st, sz_st, hist_Pm, xs_st, do_update):
    """inscal.core.kalman predict/update over the stored steps, as the pass kernel calls them
    (no navigation, no feedback bookkeeping: the closed-loop filter state is zero).
    ``do_update`` (for the profile): 2 both, 0 predict only, 1 update only."""
    N = P.shape[0]
    M = phinn_st.shape[0]
    qp = np.zeros(N - 9)
    K = np.empty((N, 6))
    Si = np.empty((6, 6))
    xs = np.empty(N)
    ih = 0
    for k in range(M):
        if do_update != 1:
            filters.predict(P, 9, phinn_st[k], phinp_st[k], Qd_st[k], qp)
        if do_update == 0:
            continue
        if k % hist_every == 0 or k == M - 1:
            hist_Pm[ih] = P
            ih += 1
        z = zs[k]
        filters.update(P, IDX_MEAS, rs, z, K, Si, xs)
        K_st[k] = K
        Si_st[k] = Si
        sz_st[k] = Si @ z
        xs_st[k] = xs


@njit(cache=True)
def _engine_backward(P0, K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, hist_Pm, hist_x, hist_P, Ppp, part):
    """The MBF smoother of inscal.core.kalman (as the smoother's smooth_steps: the constants' feedback still to
    come and their final filtered covariance ``Ppp`` into ``smoothed_constant``).  ``part`` (for the profile):
    0 all; 1 smoother_step only; 2 adjoint_back only; 3 the smoothed estimates only."""
    N = P0.shape[0]
    M = K_st.shape[0]
    lam = np.zeros(N)
    Lam = np.zeros((N, N))
    rem = np.zeros(N - 9)
    ih = hist_Pm.shape[0] - 1
    for k in range(M - 1, -1, -1):
        if part == 0 or part == 1:
            filters.smoother_step(lam, Lam, IDX_MEAS, K_st[k], Si_st[k], sz_st[k])
        if part == 0 or part == 3:
            add_feedback(rem, K_st[k], Si_st[k], sz_st[k], 9)
            if k % hist_every == 0 or k == M - 1:
                x, Ps = filters.smoothed_constant(hist_Pm[ih], lam, Lam, 9, rem, Ppp)
                hist_x[ih] = x
                hist_P[ih] = Ps
                ih -= 1
        if part == 0 or part == 2:
            filters.adjoint_back(lam, Lam, 9, phinn_st[k], phinp_st[k])
    return filters.smoothed_constant(P0, lam, Lam, 9, rem, Ppp)


@njit(cache=True)
def _rebuild_qd(phinn_st, sig, lat0, h0, g_scale, T, qgm, qam, q_used, Qd_st):
    """The pass kernel's scaled Q_d per step: recover the step's mean f^n from its scaled
    Phi_nn (fixed point on Phi[4,2], Phi[5,0], Phi[3,1] = f_E, f_N, f_U T + ...), then the kernel's own
    ``discretise`` with the accelerometer PSD times the step's factor ``q_used`` (the pass's model-error
    term and bounded-influence jumps: ``PassOutput.q_used``).  Returns max |Phi_nn(model) - Phi_nn(stored)|."""
    M = phinn_st.shape[0]
    F = np.zeros((9, 9))
    F2 = np.empty((9, 9))
    ph_model = np.empty((9, 9))
    Qd = np.empty((9, 9))
    fn = np.zeros(3)
    worst = 0.0
    for k in range(M):
        ph = np.empty((9, 9))
        for i in range(9):
            for j in range(9):
                ph[i, j] = phinn_st[k, i, j] * sig[i] / sig[j]
        fn[0] = ph[4, 2] / T
        fn[1] = ph[5, 0] / T
        fn[2] = ph[3, 1] / T
        for _ in range(6):
            nav_F(lat0, h0, fn, F, g_scale)
            F2 = F @ F
            F3 = F2 @ F
            model = np.eye(9) + F * T + F2 * (T * T / 2.0) + F3 * (T * T * T / 6.0)
            fn[0] -= (model[4, 2] - ph[4, 2]) / T
            fn[1] -= (model[5, 0] - ph[5, 0]) / T
            fn[2] -= (model[3, 1] - ph[3, 1]) / T
        nav_F(lat0, h0, fn, F, g_scale)
        discretise(F, T, qgm, qam * q_used[k], sig, F2, ph_model, Qd)
        for i in range(9):
            for j in range(9):
                e = abs(ph_model[i, j] - phinn_st[k, i, j])
                if e > worst:
                    worst = e
                Qd_st[k, i, j] = Qd[i, j]
    return worst


# ----------------------------------------------------------------------------- the dense filterpy filter
def _dense_inputs(phinn, phinp):
    M, n, p = phinp.shape
    N = n + p
    Fs = np.zeros((M, N, N))
    Fs[:, :n, :n] = phinn
    Fs[:, :n, n:] = phinp
    Fs[:, n:, n:] = np.eye(p)
    return Fs


def _filterpy_pass(Fs, Qs, R, H, zs):
    """Closed-loop dense filter (the estimate is fed back: x <- 0 after each update) and the
    filterpy RTS smoother on the equivalent open-loop means (filtered mean + accumulated,
    propagated feedback C).  Returns (t_forward, t_smoother, results)."""
    from filterpy.kalman import KalmanFilter

    M, N, _ = Fs.shape
    kf = KalmanFilter(dim_x=N, dim_z=H.shape[0])
    kf.P = np.eye(N)
    kf.R = R
    kf.H = H
    Xo = np.empty((M, N))  # open-loop filtered means
    Cp = np.empty((M, N))  # accumulated feedback, predicted to step k (before update k)
    Pf = np.empty((M, N, N))
    xs = np.empty((M, N))
    c = np.zeros(N)
    t0 = time.perf_counter()
    for k in range(M):
        kf.F = Fs[k]
        kf.Q = Qs[k]
        kf.predict()
        c = Fs[k] @ c
        kf.update(zs[k])
        x = kf.x[:, 0]
        xs[k] = x
        Cp[k] = c
        c = c + x
        Xo[k] = c
        Pf[k] = kf.P
        kf.x[:] = 0.0  # feedback
    t1 = time.perf_counter()
    xsm, Psm, _, _ = kf.rts_smoother(Xo, Pf, Fs, Qs)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, {"xs": xs, "Pf": Pf[-1], "x_smooth": xsm - Cp, "P_smooth": Psm, "x_open": xsm, "C": Cp}


# ----------------------------------------------------------------------------- memory
_CHILD = r"""
import json, sys, time, tracemalloc
import numpy as np
from types import SimpleNamespace
from inscal.sim import scenarios
from inscal.calibrate import calibrate


def status_kb(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return -1


d = np.load(sys.argv[1])
rec = SimpleNamespace(dtheta=d["dtheta"], dvel=d["dvel"], rate_hz=float(d["rate_hz"]), site=scenarios.build("s16").site)
n_warm = int(300 * rec.rate_hz)
t0 = time.perf_counter()
calibrate(SimpleNamespace(dtheta=rec.dtheta[:n_warm], dvel=rec.dvel[:n_warm], rate_hz=rec.rate_hz, site=rec.site),
          "systematic51", max_passes=2)  # numba cache load (or compilation)
t_warm = time.perf_counter() - t0
hwm_setup = status_kb("VmHWM")
try:  # reset the high-water mark (Linux >= 4.0) so that the run's own peak is measured
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    reset = True
except OSError:
    reset = False
rss_before = status_kb("VmRSS")
t0 = time.perf_counter()
calibrate(rec, "systematic51")
t_run = time.perf_counter() - t0
hwm_run = status_kb("VmHWM")
tracemalloc.start()
calibrate(rec, "systematic51")
cur, peak = tracemalloc.get_traced_memory()
tracemalloc.stop()
print(json.dumps({"warm_s": t_warm, "run_s": t_run, "hwm_setup_kb": hwm_setup, "reset": reset,
                  "rss_before_kb": rss_before, "hwm_run_kb": hwm_run,
                  "traced_peak_b": peak}))
"""


def _memory(rec) -> dict:
    """Peak memory of one full calibration in a fresh process (after the imports, the record and
    a warm-up on 300 s, whose own peak is reported apart), from the child's own high-water mark
    (VmHWM).  Not ``getrusage(RUSAGE_CHILDREN).ru_maxrss``: Linux counts in it the RSS of the
    forked image of this (large) process before the exec, which inflates it to this process's size."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "rec.npz")
        np.savez(path, dtheta=rec.dtheta, dvel=rec.dvel, rate_hz=rec.rate_hz)
        r = subprocess.run([sys.executable, "-c", _CHILD, path], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"memory subprocess failed:\n{r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


# ----------------------------------------------------------------------------- main
def _verdict(ok: bool) -> str:
    return "PASS" if ok else "MISS"


def _t(label: str, value: float, w: int, extra: str = "") -> str:
    """A figure line: the label, then ``in X s`` (the form bench/compare.py reads)."""
    return f"  {label:<{w}} in {value:>7.3f} s{extra}"


def _report_full(A: dict, passes: int, repeats: int, w: int) -> None:
    """(a): the total, the passes and where the time went."""
    tot = A["total"]
    print(_t(f"(a) full calibrate(rec, systematic51), best of {repeats}", tot, w,
             f"   < {TARGET_S:g} s {_verdict(tot < TARGET_S)}, goal {GOAL_S:g} s {_verdict(tot < GOAL_S)}"))
    print(f"  {'    passes':<{w}} {passes:>10d}")
    npass = max(A.get("run_pass#", 1), 1)
    print(_t("    per pass (run_pass: navigation, filter, smoothed states)", A.get("run_pass", math.nan) / npass, w))
    print(_t("      pass kernel (comp., nav, Jacobian, predict, update)",
             A.get("_pass_kernel", math.nan) / max(A.get("_pass_kernel#", 1), 1), w))
    print(_t("      adjoint recursion (smoothed states)",
             A.get("smooth_vector_kernel", 0.0) / max(A.get("smooth_vector_kernel#", 1), 1), w))
    print(_t("    all passes (run_pass)", A.get("run_pass", math.nan), w))
    known = A.get("run_pass", 0.0)
    for label, names in PHASES:
        v = sum(A.get(nm, 0.0) for nm in names)
        known += v
        print(_t(f"    driver: {label}", v, w))
    print(_t("    driver: rest (prior change, result, fit)", tot - known, w))


def _report_memory(mem: dict, w: int) -> None:
    """(d): the peak memory of a fresh process."""
    mb = max(mem["hwm_setup_kb"], mem["hwm_run_kb"]) / 1024
    print(f"  {'(d) peak RSS of a fresh process running one full calibration':<{w}} {mb:>7.0f} MB   "
          f"< {TARGET_MB:g} MB {_verdict(mb < TARGET_MB)}")
    lab = "      before the run: imports, record, compiled code"
    print(f"  {lab:<{w}} {mem['rss_before_kb'] / 1024:>7.0f} MB")
    if mem["reset"]:
        print(f"  {'      peak during the run (high-water mark reset before it)':<{w}} "
              f"{mem['hwm_run_kb'] / 1024:>7.0f} MB   "
              f"(+{(mem['hwm_run_kb'] - mem['rss_before_kb']) / 1024:.0f} MB)")
    print(f"  {'      tracemalloc peak of one calibration (NumPy arrays)':<{w}} "
          f"{mem['traced_peak_b'] / 2**20:>7.0f} MB")
    print(f"  {'      peak before the run (incl. a 300 s warm-up calibration)':<{w}} "
          f"{mem['hwm_setup_kb'] / 1024:>7.0f} MB   (warm-up {mem['warm_s']:.1f} s"
          + (": numba compiled, the cache was stale)" if mem["warm_s"] > 5 else ": numba cache)"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=2, help="timed runs of the full calibration (best); the "
                    "single-pass figures take max(3, repeats)")
    ap.add_argument("--no-memory", action="store_true", help="skip the peak-memory subprocess")
    ap.add_argument("--no-filterpy", action="store_true", help="skip the dense filterpy comparison")
    ap.add_argument("--e2e", action="store_true", help="only the end-to-end calibration (a) and its peak memory (d)")
    a = ap.parse_args(argv)
    reps1 = max(3, a.repeats)
    load0 = os.getloadavg()

    t0 = time.perf_counter()
    sc, rec = _record()
    t_sim = time.perf_counter() - t0
    n = rec.dtheta.shape[0]
    # warm-up (compilation or numba cache load), not timed
    t0 = time.perf_counter()
    calibrate(_slice(rec, int(300 * rec.rate_hz)), "systematic51", max_passes=2)
    t_warm = time.perf_counter() - t0

    # (a) full calibration
    runs = []
    for _ in range(a.repeats):
        acc: dict = {}
        with _timers(acc):
            t0 = time.perf_counter()
            res = calibrate(rec, "systematic51")
            acc["total"] = time.perf_counter() - t0
        runs.append(acc)
    A = min(runs, key=lambda r: r["total"])
    passes = len(res.diagnostics["passes"])
    steps = int(res.diagnostics["steps"])
    N = int(res.diagnostics["states"])
    w = 62
    print(f"bench_systematic: s16 record, {n} samples ({n / rec.rate_hz / 3600:.2f} h at {rec.rate_hz:g} Hz), "
          f"{steps} filter steps, {N} states; simulate {t_sim:.2f} s, warm-up {t_warm:.1f} s (not timed)")
    cores, load = os.cpu_count() or 1, load0
    print(f"  {cores} cores, load average {load[0]:.1f} at the start, {os.getloadavg()[0]:.1f} now"
          + ("  (busy machine: other processes share the cores, the times are inflated)" if load[0] > 0.75 * cores
             else ""))
    _report_full(A, passes, a.repeats, w)
    if a.e2e:
        if not a.no_memory:
            _report_memory(_memory(rec), w)
        return 0

    # (b) one pass; capture its arguments
    keep: dict = {}
    with _timers({}, keep):
        calibrate(rec, "systematic51", max_passes=1)
    t_b, _ = _best(lambda: calibrate(rec, "systematic51", max_passes=1), reps1)
    ba = inspect.signature(run_pass).bind(*keep["run_pass"][0], **keep["run_pass"][1])
    ba.apply_defaults()
    pa = dict(ba.arguments)
    pa["keep_phi"] = True
    pa["smooth"] = True  # the full smoother too: its covariances for (c)
    runs_b = []
    for _ in range(reps1):
        accb: dict = {}
        with _timers(accb):
            out = DRIVER.run_pass(**{**pa, "params": pa["params"].copy()})
        runs_b.append(accb)
    B = min(runs_b, key=lambda r: r["run_pass"])
    t_pass, t_kern, t_smooth = B["run_pass"], B.get("_pass_kernel", math.nan), B.get("smooth_kernel", math.nan)

    # the kernel with no parameter states (navigation + compensation + a 9-state filter)
    t_kern9 = None
    try:
        kargs, _ = keep["_pass_kernel"]
        inp, par, P, st, er = kargs
        M = st.K_st.shape[0]
        nh = st.hist_Pm.shape[0]
        ei = np.zeros(0, dtype=inp.kinds.dtype)
        inp9 = inp._replace(kinds=ei, axes=ei.copy(), js=ei.copy(), sig=np.ascontiguousarray(inp.sig[:9]))
        st9 = st._replace(K_st=np.empty((M, 9, 6)), phinp_st=np.empty((M, 9, 0)), hist_Pm=np.empty((nh, 9, 9)),
                          hist_Pf=np.empty((nh, 9)))

        def _k9():
            return _pass_kernel(_copy(inp9), _copy(par), np.eye(9), _copy(st9), _copy(er))

        def _k51():
            return _pass_kernel(*[_copy(v) for v in kargs])

        _k9()
        t_kern9, _ = _best(_k9, reps1)
        t_kern, _ = _best(_k51, reps1)
    except Exception as exc:  # the kernel's signature moved on: report without this split
        print(f"  (no navigation-only split: {type(exc).__name__}: {exc})")

    # the structured engine on the stored data (no navigation)
    sig = pa["sig"]
    N = sig.shape[0]
    T = pa["n_per"] * pa["dt"]
    site = np.asarray(pa["site"], float)
    Qd = np.empty((steps, 9, 9))
    g_scale = float(site[3]) if site.shape[0] > 3 else 1.0
    phi_err = _rebuild_qd(out.phinn, sig, site[0], site[2], g_scale, T, float(np.mean(pa["qg"])),
                          float(np.mean(pa["qa"])), np.ascontiguousarray(out.q_used[:steps]), Qd)
    rs = pa["r"] / sig[3:9] ** 2
    if np.any(out.r_factor[:steps] != 1.0):
        print("  (the pass ran with per-step factors on R: the replay's constant R differs from it)")
    zs = out.z / sig[3:9]
    he = int(pa["hist_every"])
    nh = out.hist_Pm.shape[0]

    def fwd(do_update=2):
        st = dict(P=np.eye(N), K=np.empty((steps, N, 6)), Si=np.empty((steps, 6, 6)), sz=np.empty((steps, 6)),
                  Pm=np.empty((nh, N, N)), xs=np.empty((steps, N)))
        _engine_forward(st["P"], out.phinn, out.phinp, Qd, rs, zs, he, st["K"], st["Si"], st["sz"], st["Pm"],
                        st["xs"], do_update)
        return st

    def bwd(st, part=0):
        hx, hP = np.empty((nh, N)), np.empty((nh, N, N))
        x0, P0 = _engine_backward(np.eye(N), st["K"], st["Si"], st["sz"], out.phinn, out.phinp, he, st["Pm"], hx, hP,
                                  np.ascontiguousarray(st["P"][9:, 9:]), part)
        return hx, hP, x0, P0

    fwd(), bwd(fwd())  # compile
    t_fwd, eng = _best(fwd, reps1)
    t_pred, _ = _best(lambda: fwd(0), reps1)
    t_upd, _ = _best(lambda: fwd(1), reps1)
    t_bwd, (hx, hP, x0, P0) = _best(lambda: bwd(eng), reps1)
    t_bwd1, _ = _best(lambda: bwd(eng, 1), reps1)
    t_bwd2, _ = _best(lambda: bwd(eng, 2), reps1)
    t_bwd3, _ = _best(lambda: bwd(eng, 3), reps1)
    t_engine = t_fwd + t_bwd
    # replay == pass (same operations, same inputs)
    replay_dev = max(float(np.max(np.abs(eng["P"] - out.Pf))), float(np.max(np.abs(hx - out.hist_x))),
                     float(np.max(np.abs(x0 - out.x0s))))

    # (c) dense filterpy
    dense = None
    if not a.no_filterpy:
        try:
            import filterpy  # noqa: F401
        except ImportError:
            print("  filterpy is not installed (pip install '.[bench]'): no dense comparison")
        else:
            Fs = _dense_inputs(out.phinn, out.phinp)
            Qs = np.zeros((steps, N, N))
            Qs[:, :9, :9] = Qd
            H = np.zeros((6, N))
            H[np.arange(6), IDX_MEAS] = 1.0
            tf, ts, dres = _filterpy_pass(Fs, Qs, np.diag(rs), H, zs)
            hs = out.hist_step
            pf = np.diag(out.Pf)
            sdp = np.sqrt(pf[9:])
            dx = dres["x_smooth"][hs] - out.hist_x
            dgo = np.diagonal(out.hist_P, axis1=1, axis2=2)
            dgd = np.diagonal(dres["P_smooth"][hs], axis1=1, axis2=2)
            # constant parameters: the open-loop smoothed parameters and their smoothed covariance are
            # the final filtered ones at every step (an exact invariant, checked for both smoothers)
            xo, c = dres["x_open"], dres["C"]
            # ours: the pass's own feedback (K z of every update), accumulated to each step's reference; not the
            # dense replay's, whose filter may differ from the pass (a Q_d or R that is not the pass's)
            fb = np.einsum("kna,ka->kn", out.smoother.K_st[:steps, 9:], zs)
            c_pass = np.concatenate([np.zeros((1, N - 9)), np.cumsum(fb, axis=0)])
            dense = {
                "t_fwd": tf, "t_smooth": ts,
                "Pf_diag_rel": float(np.max(np.abs(np.diag(dres["Pf"]) - pf) / pf)),
                "xf_last": float(np.max(np.abs(dres["xs"][-1] - eng["xs"][-1]) / np.sqrt(pf))),
                "xs_abs": float(np.max(np.abs(dx))),
                # the first stored step (step 0: its predicted covariance is the prior's) apart from the others
                "xs_nav_sig": (float(np.max(np.abs(dx[0, :9]) / np.sqrt(np.abs(dgd[0, :9])))),
                               float(np.max(np.abs(dx[1:, :9]) / np.sqrt(np.abs(dgd[1:, :9]))))),
                "xs_par_post": float(np.max(np.abs(dx[:, 9:]) / sdp)),
                "xs_par_last": float(np.max(np.abs(dx[-1, 9:]) / sdp)),
                "Ps_abs": float(np.max(np.abs(dgd - dgo))),
                "inv_x": (float(np.max(np.abs(out.hist_x[:, 9:] + c_pass[hs] - c_pass[-1]) / sdp)),
                          float(np.max(np.abs(xo[hs, 9:] - xo[-1, 9:]) / sdp))),
                "inv_P": (float(np.max(np.abs(dgo[:, 9:] - pf[9:]))), float(np.max(np.abs(dgd[:, 9:] - pf[9:])))),
                "neg": (int(np.sum(np.any(dgo <= 0, axis=1))), int(np.sum(np.any(dgd <= 0, axis=1)))),
                "nh": len(hs),
            }
            del Fs, Qs, dres

    mem = None
    if not a.no_memory:
        mem = _memory(rec)

    # ------------------------------------------------------------------ report
    print(f"  {'(b) single pass calibrate(..., max_passes=1), best of ' + str(reps1):<{w}} in {t_b:>7.3f} s")
    print(f"  {'    run_pass (navigation + filter + smoother)':<{w}} in {t_pass:>7.3f} s")
    print(f"  {'      pass kernel, 51 states':<{w}} in {t_kern:>7.3f} s")
    if t_kern9 is not None:
        print(f"  {'        same kernel, 9 states (compensation + navigation)':<{w}} in {t_kern9:>7.3f} s")
        print(f"  {'        => Jacobian accumulation + Phi_np (51 - 9 - engine fwd)':<{w}} "
              f"in {t_kern - t_kern9 - t_fwd:>7.3f} s")
    print(f"  {'      smoother kernel':<{w}} in {t_smooth:>7.3f} s")
    print(f"  {'    structured engine alone (inscal.core.kalman, replayed):':<{w}}")
    print(f"  {'      predict':<{w}} in {t_pred:>7.3f} s   ({t_pred / steps * 1e6:.1f} us/step)")
    print(f"  {'      update (Joseph)':<{w}} in {t_upd:>7.3f} s   ({t_upd / steps * 1e6:.1f} us/step)")
    print(f"  {'      filter: predict + update (one loop)':<{w}} in {t_fwd:>7.3f} s")
    print(f"  {'      smoother: smoother_step':<{w}} in {t_bwd1:>7.3f} s   ({t_bwd1 / steps * 1e6:.1f} us/step)")
    print(f"  {'      smoother: adjoint_back':<{w}} in {t_bwd2:>7.3f} s   ({t_bwd2 / steps * 1e6:.1f} us/step)")
    print(f"  {f'      smoother: smoothed estimates ({nh} stored steps)':<{w}} in {t_bwd3:>7.3f} s")
    print(f"  {'      smoother: all (one loop)':<{w}} in {t_bwd:>7.3f} s")
    print(f"  {'      engine filter + smoother':<{w}} in {t_engine:>7.3f} s   (replay == pass: max abs dev "
          f"{replay_dev:.1e})")
    if dense is not None:
        td = dense["t_fwd"] + dense["t_smooth"]
        r_eng, r_pass = td / t_engine, td / t_pass
        print(f"  {'(c) dense filterpy filter + rts_smoother (no navigation)':<{w}} in {td:>7.3f} s")
        print(f"  {'      predict + update (KalmanFilter, dim_x=51, dim_z=6)':<{w}} in {dense['t_fwd']:>7.3f} s   "
              f"({dense['t_fwd'] / steps * 1e6:.0f} us/step)")
        print(f"  {'      rts_smoother':<{w}} in {dense['t_smooth']:>7.3f} s   "
              f"({dense['t_smooth'] / steps * 1e6:.0f} us/step)")
        print(f"  {'    ratio (c) / engine filter + smoother':<{w}} {r_eng:>8.1f} x   >= {TARGET_RATIO:g} x "
              f"{_verdict(r_eng >= TARGET_RATIO)}")
        print(f"  {'    ratio (c) / whole pass incl. navigation (conservative)':<{w}} {r_pass:>8.1f} x   "
              f">= {TARGET_RATIO:g} x {_verdict(r_pass >= TARGET_RATIO)}")
        print(f"  {'    check dense == structured (scaled states: prior sigma = 1)':<{w}}")
        print(f"  {'      Q_d rebuilt: max |Phi_nn(model) - Phi_nn(pass)|':<{w}} {phi_err:>10.1e}")
        print(f"  {'      filtered P diagonal, last step: max rel. diff':<{w}} {dense['Pf_diag_rel']:>10.1e}")
        print(f"  {'      filtered estimate, last step: max diff / sigma':<{w}} {dense['xf_last']:>10.1e}")
        print(f"  {'      smoothed parameters, last step: max diff / sigma':<{w}} {dense['xs_par_last']:>10.1e}")
        lab = f"      smoothed states, {dense['nh']} stored steps: max diff"
        print(f"  {lab:<{w}} {dense['xs_abs']:>10.1e}")
        print(f"  {'        parameters: max diff / final sigma':<{w}} {dense['xs_par_post']:>10.1e}")
        print(f"  {'        navigation / dense smoothed sigma: first stored step':<{w}} {dense['xs_nav_sig'][0]:>10.1e}")
        print(f"  {'        navigation / dense smoothed sigma: the others':<{w}} {dense['xs_nav_sig'][1]:>10.1e}")
        print(f"  {'      smoothed P diagonal, stored steps: max diff':<{w}} {dense['Ps_abs']:>10.1e}")
        print(f"  {'    invariant (constant parameters), ours | filterpy:':<{w}}")
        print(f"  {'      smoothed params = final filtered: max dev / sigma':<{w}} "
              f"{dense['inv_x'][0]:>10.1e} | {dense['inv_x'][1]:.1e}")
        print(f"  {'      smoothed P_pp diag = final filtered: max dev':<{w}} "
              f"{dense['inv_P'][0]:>10.1e} | {dense['inv_P'][1]:.1e}   (final P_pp diag min {np.min(pf[9:]):.1e})")
        print(f"  {'      stored steps with a smoothed variance <= 0':<{w}} "
              f"{dense['neg'][0]:>10d} | {dense['neg'][1]}")
    if mem is not None:
        _report_memory(mem, w)
    return 0


if __name__ == "__main__":
    sys.exit(main())
