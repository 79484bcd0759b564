"""Benchmark: simulate the full built-in ``s16`` scenario (S16 Table 1, ~1.07 h at 100 Hz,
386,100 samples, every error term and noise) in memory, after compilation.

Lines (best of ``--repeats`` runs each, after a first run that compiles or loads the numba cache):

1. ``s16`` with its full error model and noise (the figure ``bench/compare.py`` reads first);
2. ``rotmod16`` (6 h of 16-sequence rotation modulation) with a perfect IMU and no noise;
3. the parts of line 1, measured by switching them on one after the other on the ``s16`` path (the
   three runs taken in turn, so that they see the same machine): the motion (integrals of the gimbal
   kinematics and the recorded gimbal angles: a perfect IMU, no noise), the error model (full model,
   no noise, minus the motion) and the noise (with noise minus without).  These lines mean the same
   on any revision of the simulator;
4. the parts as this revision's code has them, timed one by one (in ms, so ``compare.py`` does not pair
   them with the other revision's, whose parts differ): before the compiled pass, the kinematics
   kernel, ``Segments.angles``, ``ImuErrors.measure_increments`` and ``NoiseState.apply``; with it,
   the NumPy normal draws (``NoiseState.draw``) and the compiled pass (everything else, writing fresh
   output arrays), each timed alone.

``--load N`` runs N busy processes (``python -c "while True: pass"``) during the measurement and
kills them afterwards, for the figures under load.

Run: python bench/bench_simulate.py [--repeats R] [--load N]
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import time

import numpy as np

from inscal.core.error_model import ImuErrors, ImuNoise
from inscal.sim import scenarios
from inscal.sim import simulate as sim
from inscal.sim.simulate import simulate


def timed(fn, repeats: int) -> tuple[float, float]:
    """(best, median) seconds of ``repeats`` calls, after one untimed call."""
    return timed_together([fn], repeats)[0]


def timed_together(fns, repeats: int) -> list[tuple[float, float]]:
    """:func:`timed` of several functions, their calls taken in turn (so that they see the same machine)."""
    for fn in fns:
        fn()
    times = [[] for _ in fns]
    for _ in range(repeats):
        for fn, ts in zip(fns, times):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
    return [(min(ts), float(np.median(ts))) for ts in times]


def figure(label: str, sc, n: int, best: float, median: float, repeats: int) -> str:
    return (f"simulate {label}: {n} samples ({n / sc.rate_hz / 3600:.2f} h at {sc.rate_hz:g} Hz) in {best:.3f} s "
            f"(best of {repeats}; median {median:.3f} s) = {n / best / 1e6:.2f} M samples/s")


def internal_parts(sc, repeats: int) -> str:
    """The parts of the ``s16`` run as the code of this revision has them (ms)."""
    n, dt = sc.n_samples, 1.0 / sc.rate_hz
    if hasattr(sim, "PASS_ROWS"):  # the compiled pass: only the normal draws are outside it
        def draws():
            st = sim.NoiseState(sc.noise, np.random.default_rng(1), dt)
            for j0 in range(0, n, sim.PASS_ROWS):
                st.draw(min(sim.PASS_ROWS, n - j0))

        b_draw, m_draw = timed(draws, repeats)
        # the pass alone: the whole run in one pass, noise drawn beforehand, into fresh outputs
        seg = sc.path.segments()
        model = sim.ModelArrays.of(sc.imu)
        nopts, nargs = sim.NoiseState(sc.noise, np.random.default_rng(1), dt).pass_arguments(n)
        u = sim.outer_axis(sc.gimbal.nonorthogonality)
        Cbn = np.ascontiguousarray(sim.dcm_from_euler(sc.gimbal.mount_attitude))
        wie, g = np.array(sc.site.earth_rate_n), float(sc.site.gravity)
        r3, r6 = np.zeros((1, 3)), np.zeros((1, 6))

        def one_pass():
            sim.simulate_pass(0, n, dt, (seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn, wie, g), sim._GL_X,
                              sim._GL_W, model.opts | sim.O_RECORD | nopts, model.arrays, (r3, r3, r3, r6, r3), nargs,
                              np.zeros(4), (np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 2)), r3, r3,
                                            r3, r3, r6, r3))

        b_pass, m_pass = timed(one_pass, repeats)
        return (f"parts of s16 in this code, best (median): noise draws (NumPy) {ms(b_draw, m_draw)}; compiled pass "
                f"(kinematics, angles, error model, noise; into fresh outputs) {ms(b_pass, m_pass)}")
    seg = sc.path.segments()
    u = sim.outer_axis(sc.gimbal.nonorthogonality)
    Cbn = np.ascontiguousarray(sim.dcm_from_euler(sc.gimbal.mount_attitude))
    wie, g = sc.site.earth_rate_n, sc.site.gravity
    out = [np.empty((n, 3)) for _ in range(5)] + [np.empty((n, 6))]
    dth, dv, f2, fx, dw, ww = out
    b_kernel, m_kernel = timed(lambda: sim._simulate_kernel(0, n, dt, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn,
                                                            wie, g, sim._GL_X, sim._GL_W, True, dth, dv, f2, fx, ww, dw),
                               repeats)
    t = (1 + np.arange(n)) * dt
    b_angles, m_angles = timed(lambda: seg.angles(t), repeats)
    b_model, m_model = timed(lambda: sc.imu.measure_increments(dt, dth, dv, f2, fx, ww, dw), repeats)
    gim = np.zeros((n, 2))
    b_noise, m_noise = timed(lambda: sim.NoiseState(sc.noise, np.random.default_rng(1), dt).apply(dth, dv, gim), repeats)
    return (f"parts of s16 in this code, best (median): kinematics kernel {ms(b_kernel, m_kernel)}; angles "
            f"{ms(b_angles, m_angles)}; error model {ms(b_model, m_model)}; noise {ms(b_noise, m_noise)}")


def ms(best: float, median: float) -> str:
    return f"{best * 1e3:.1f} ms ({median * 1e3:.1f} ms)"


def busy(n: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--load", type=int, default=0, help="busy processes running during the measurement")
    a = ap.parse_args(argv)
    r = a.repeats
    s16 = scenarios.build("s16")
    quiet = dataclasses.replace(s16, noise=ImuNoise())
    motion = dataclasses.replace(quiet, imu=ImuErrors())
    rotmod = scenarios.build("rotmod16")
    procs = busy(a.load)
    try:
        lines = []
        b, med = timed(lambda: simulate(s16, np.random.default_rng(0)), r)
        lines.append(figure("s16", s16, s16.n_samples, b, med, r) + (f" (under --load {a.load})" if a.load else ""))
        b_rot, med_rot = timed(lambda: simulate(rotmod), r)
        lines.append(figure("rotmod16 perfect IMU", rotmod, rotmod.n_samples, b_rot, med_rot, r))
        (b_full, _), (b_quiet, _), (b_motion, _) = timed_together(
            [lambda: simulate(s16, np.random.default_rng(0)), lambda: simulate(quiet), lambda: simulate(motion)], r)
        lines.append(f"part motion and gimbal angles (s16 path, perfect IMU, no noise): {b_motion:.4f} s")
        lines.append(f"part error model (s16 full model, no noise, minus the motion): {b_quiet - b_motion:.4f} s")
        lines.append(f"part noise (s16 with noise, minus without): {b_full - b_quiet:.4f} s")
        lines.append(internal_parts(s16, r))
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait()
    print("\n".join(lines))


if __name__ == "__main__":
    main()
