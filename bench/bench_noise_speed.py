"""Speed and memory of the streamed Allan / Haar wavelet variance (inscal.analysis.noise.estimators)
against allantools.oadev on a long six-channel record (default: 24 h at 100 Hz), and the identification
with model selection of its six channels.  Each measurement runs in its own process (peak RSS from
getrusage); the record is generated chunk by chunk from a seeded generator (the engine never holds
it), allantools gets each channel as one array (it needs the whole series).

    .venv/bin/python bench/bench_noise_speed.py --hours 24 --rate 100
"""

from __future__ import annotations

import argparse
import resource
import time
from multiprocessing import get_context

import numpy as np

CH = 6


def chunks(n, seed, chunk=1 << 18):
    rng = np.random.default_rng(seed)
    walk = np.zeros(CH)
    for a in range(0, n, chunk):
        k = min(chunk, n - a)
        steps = np.cumsum(rng.normal(0, 1e-7, (k, CH)), axis=0) + walk
        walk = steps[-1]
        yield rng.normal(0, 1e-4, (k, CH)) + steps


def run_engine(n, rate, q):
    """The engine fed chunk by chunk as they are generated; its own time (the updates and the result)
    is measured apart from the generator's."""
    from inscal.analysis.noise.estimators import StreamingScaleVariance, octave_scales

    t0, c0 = time.perf_counter(), time.process_time()
    tiny = StreamingScaleVariance(4096, rate, CH, [1, 2], piece=1024, increments=False)
    tiny.update(np.zeros((4096, CH)))  # the compiled kernels loaded from numba's cache: once per process
    load = (time.perf_counter() - t0, time.process_time() - c0)
    wall = cpu = 0.0
    acc = StreamingScaleVariance(n, rate, CH, octave_scales(n), increments=False)
    for x in chunks(n, 1):
        t0, c0 = time.perf_counter(), time.process_time()
        acc.update(x)
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
    t0, c0 = time.perf_counter(), time.process_time()
    sv = acc.result()
    wall += time.perf_counter() - t0
    cpu += time.process_time() - c0
    q.put(("engine", wall, cpu, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, (sv.adev, load)))


def run_generator(n, rate, q):
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in chunks(n, 1):
        pass
    q.put(("generator", time.perf_counter() - t0, time.process_time() - c0,
           resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, None))


def run_allantools(n, rate, q):
    import allantools

    from inscal.analysis.noise.estimators import octave_scales

    x = np.concatenate(list(chunks(n, 1)))
    t0, c0 = time.perf_counter(), time.process_time()
    out = []
    for c in range(CH):  # (the timing stops after the six channels, below)
        _, ad, _, _ = allantools.oadev(np.ascontiguousarray(x[:, c]), rate=rate, data_type="freq",
                                       taus=octave_scales(n) / rate)
        out.append(ad)
    t1, c1 = time.perf_counter() - t0, time.process_time() - c0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    # an exact reference for channel 0: the phase and the second differences in extended precision
    # (numpy.longdouble, 80-bit on x86), the mean removed first (no D changes), in pieces
    y0 = x[:, 0].copy()
    del x
    xl = y0.astype(np.longdouble)
    xl -= xl.mean()
    ph = np.concatenate([np.zeros(1, dtype=np.longdouble), np.cumsum(xl)])
    del xl
    ref = []
    for m in octave_scales(n):
        tot, cnt = np.longdouble(0), ph.size - 2 * m
        for a in range(0, cnt, 1 << 20):
            b = min(cnt, a + (1 << 20))
            d = ph[a + 2 * m:b + 2 * m] - 2 * ph[a + m:b + m] + ph[a:b]
            tot += np.sum(d * d)
        ref.append(float(np.sqrt(tot / (2 * m * m * cnt))))
    q.put(("allantools", t1, c1, rss, (np.array(out).T, np.array(ref))))


def run_identify(n, rate, q):
    from inscal.analysis.noise.estimators import StreamingScaleVariance, log_scales
    from inscal.analysis.noise.identify import identify_curve, octave_curve

    t0, c0 = time.perf_counter(), time.process_time()
    acc = StreamingScaleVariance(n, rate, CH, log_scales(n, 4), increments=False)
    for x in chunks(n, 1):
        acc.update(x)
    sv = acc.result()
    models = [identify_curve(octave_curve(sv, c), "auto", np.random.default_rng(c)).chosen.model for c in range(CH)]
    q.put(("identify", time.perf_counter() - t0, time.process_time() - c0,
           resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, models))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--only", choices=("identify",), help="run only the identification")
    a = ap.parse_args()
    n = int(a.hours * 3600 * a.rate)
    ctx = get_context("spawn")
    res = {}
    for fn in ((run_identify,) if a.only else (run_generator, run_engine, run_allantools, run_identify)):
        q = ctx.Queue()
        p = ctx.Process(target=fn, args=(n, a.rate, q))
        p.start()
        r = q.get()
        p.join()
        res[r[0]] = r
        print(f"{r[0]:<11} wall {r[1]:8.1f} s  cpu {r[2]:8.1f} s  peak RSS {r[3]:8.0f} MiB")
    if a.only:
        print(f"models chosen: {res['identify'][4]}")
        return
    e, t, g = res["engine"], res["allantools"], res["generator"]
    tad, ref = t[4]
    ead, load = e[4]
    e = e[:4] + (ead,)
    print(f"{n} samples x {CH} channels ({a.hours:g} h at {a.rate:g} Hz): engine vs allantools.oadev "
          f"max relative difference {np.max(np.abs(e[4] / tad - 1)):.2e}; against the extended-precision reference "
          f"(channel 0): engine {np.max(np.abs(e[4][:, 0] / ref - 1)):.2e}, allantools {np.max(np.abs(tad[:, 0] / ref - 1)):.2e}; "
          f"wall speed-up {t[1] / e[1]:.1f}x, cpu speed-up {t[2] / e[2]:.1f}x (the engine's own time; the "
          f"record's generation, {g[2]:.1f} s cpu, apart; with the one-time load of the compiled kernels, "
          f"{load[1]:.2f} s cpu, {t[2] / (e[2] + load[1]):.1f}x); models chosen: {res['identify'][4]}")


if __name__ == "__main__":
    main()
