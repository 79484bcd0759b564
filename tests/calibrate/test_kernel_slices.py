"""The systematic filter's pass and smoother kernels run in slices of filter steps (inscal.core.slices), so
that SIGINT/SIGTERM is honoured between two calls.  The results must not depend on the slicing:
bit-identical to one call over all the steps, whatever the slice sizes (one step, a prime number, the
adaptive slices of the real driver), for the 51-state set and for the unified set (gimbal states: the
encoder attitude rows, every third step, so that slices start on steps with and without them).  And
:func:`pass_bytes` counts what a pass keeps."""

from types import SimpleNamespace

import numpy as np
import pytest
from slicings import one_call, slicings

from inscal.calibrate.systematic import driver
from inscal.calibrate.systematic import kernel as K
from inscal.calibrate.systematic import smoother as SM
from inscal.calibrate.systematic.params import CompParams
from inscal.calibrate.systematic.states import StateSet
from inscal.core import slices
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

#: the first 900 s of the s16 record (the first dwell, then outer and inner moves) at a 2 Hz filter rate:
#: 1800 steps, a history row every 20 (the last step off that grid)
SECONDS, FILTER_HZ = 900.0, 2.0


SLICINGS = slicings(slices.run_in_slices)


@pytest.fixture(scope="module")
def record():
    sc = scenarios.build("s16")
    d = simulate(sc, np.random.default_rng(5))
    n = int(SECONDS * sc.rate_hz)
    return SimpleNamespace(time=d.time[:n], dtheta=d.dtheta[:n], dvel=d.dvel[:n], gimbal=d.gimbal[:n],
                           rate_hz=sc.rate_hz, site=sc.site, path=sc.path)


class Captured(Exception):
    pass


def pass_arguments(record, spec: str) -> tuple[tuple, dict]:
    """The arguments of the first run_pass of a systematic calibration of ``record`` (captured), with the
    full smoother and the transitions kept."""
    seen = {}

    def capture(*a, **kw):
        seen["args"] = (a, kw)
        raise Captured

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(driver, "run_pass", capture)
        with pytest.raises(Captured):
            driver.systematic(record, spec, filter_rate_hz=FILTER_HZ, encoder_every=3)
    a, kw = seen["args"]
    return a, kw | {"keep_phi": True, "smooth": True}


def outputs(args) -> dict:
    """Every array of a pass and its smoother (``run_pass(..., smooth=True)``), by name."""
    a, kw = args
    out = K.run_pass(*[x.copy() if hasattr(x, "copy") else x for x in a], **kw)
    arrays = {f"params.{k}": v for k, v in vars(out.params).items() if isinstance(v, np.ndarray)}
    for name in ("P0s", "x0s", "nis", "z", "hist_step", "hist_ref", "hist_x", "hist_P", "hist_Pm", "Pf", "phinn",
                 "phinp", "att_used", "nis_att", "z_att", "H_att", "R_att", "r_factor", "Uf"):
        v = getattr(out, name)
        if v is not None:
            arrays[name] = v
    for name, v in out.smoother._asdict().items():
        if isinstance(v, np.ndarray):
            arrays[f"smoother.{name}"] = v
    arrays["steps"] = np.array(out.steps)
    return arrays


CASES = {"51": "51", "unified (encoder rows)": "unified"}


@pytest.mark.parametrize("case", CASES)
def test_pass_and_smoother_do_not_depend_on_the_slicing(record, case, monkeypatch):
    args = pass_arguments(record, CASES[case])
    for mod in (K, SM):  # the forward pass and the smoother each slice their own loop
        monkeypatch.setattr(mod, "run_in_slices", one_call)
    ref = outputs(args)
    assert int(ref["steps"]) == int(SECONDS * FILTER_HZ)
    assert ref["hist_step"].shape[0] > 10 and (int(ref["steps"]) - 1) % 20 != 0
    if case != "51":
        used = ref["att_used"]
        assert 0 < used.sum() < used.shape[0]  # steps with and without encoder rows
    for name, run in SLICINGS.items():
        calls = []

        def counted(total, kernel, _run=run, _calls=calls, **kw):
            _calls.append(_run(total, kernel, **kw))
            return _calls[-1]

        for mod in (K, SM):
            monkeypatch.setattr(mod, "run_in_slices", counted)
        got = outputs(args)
        assert got.keys() == ref.keys(), name
        for key in ref:
            assert np.array_equal(got[key], ref[key], equal_nan=True), f"{name}: {key}"
        assert len(calls) == 3  # the forward pass, the adjoint vector, the full smoother
        if name != "default":
            assert min(calls) > 1, (name, calls)


def test_one_step_is_unchanged_by_the_slices(record, monkeypatch):
    """The F-block harness (one filter step, no update) gives the same with the slices' driver."""
    st = StateSet.parse("51,lever9,async")
    nav0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, record.site.latitude, record.site.longitude, 0.0])
    site = np.array([record.site.latitude, record.site.longitude, 0.0])
    seg = slice(18_000, 18_100)  # a move
    monkeypatch.setattr(K, "run_in_slices", one_call)
    ref = K.one_step(record.dtheta[seg], record.dvel[seg], 0.01, nav0, site, CompParams(), st)
    monkeypatch.setattr(K, "run_in_slices", slices.run_in_slices)
    got = K.one_step(record.dtheta[seg], record.dvel[seg], 0.01, nav0, site, CompParams(), st)
    for x, y in zip(ref, got):
        assert np.array_equal(x, y)


def _unique_nbytes(arrays) -> int:
    """Bytes of the distinct arrays (views and repeats counted once)."""
    seen, total = set(), 0
    for a in arrays:
        if isinstance(a, np.ndarray):
            base = a if a.base is None else a.base
            if id(base) not in seen:
                seen.add(id(base))
                total += base.nbytes
    return total


@pytest.mark.parametrize("spec", ["51", "unified"])
def test_pass_bytes_counts_what_a_pass_keeps(record, spec):
    a, kw = pass_arguments(record, spec)
    kw = kw | {"keep_phi": False}
    out = K.run_pass(*a, **kw)
    st, he, M = a[7], a[12], out.steps
    enc = kw.get("enc")
    every = [out.nis, out.z, out.r_factor, out.hist_ref, out.hist_Pm, out.hist_x, out.hist_P, out.att_used,
             out.nis_att, out.z_att, enc]
    kept = every + list(out.smoother._asdict().values())
    assert _unique_nbytes(kept) <= K.pass_bytes(M, st, he) <= 1.02 * _unique_nbytes(kept)
    light = out.without_stores()
    assert light.smoother is None and light.hist_x is out.hist_x
    assert _unique_nbytes(every) <= K.pass_bytes(M, st, he, stores=False) <= 1.1 * _unique_nbytes(every)
    if spec == "51":
        # 7.1 kB a step: 15 N + 50 floats, and Q_d (81) for the square-root information smoother
        assert K.pass_bytes(1e6, st, 10**9) / 1e6 == pytest.approx(8 * (15 * 51 + 50 + 81), rel=1e-3)


def test_run_in_slices_runs_the_check_after_each_call():
    """core knows no files: the cancellation check is handed in and runs between two kernel calls."""
    seen = []

    def check():
        seen.append(("check", len(seen)))
        if sum(1 for s in seen if s[0] == "kernel") == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        slices.run_in_slices(10**6, lambda k0, k1: seen.append(("kernel", k0, k1)), first=5, check=check)
    kinds = [s[0] for s in seen]
    assert kinds == ["kernel", "check"] * 3
    assert next(s[1:] for s in seen if s[0] == "kernel") == (0, 5)
