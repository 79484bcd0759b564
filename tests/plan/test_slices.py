"""The plan kernels run in slices of filter steps (inscal.plan.slices), so that SIGINT/SIGTERM is
honoured between two calls; the results must not depend on the slicing: bit-identical to one call
over all the steps, whatever the slice sizes (one step, a prime number, the adaptive slices)."""

import itertools
import math
import time

import numpy as np
import pytest
from slicings import one_call, slicings

from inscal.core.turntable import Move, RotationPath, s16_table1
from inscal.plan import bound as C
from inscal.plan import observability as O
from inscal.plan import slices
from inscal.plan.rows import BiasNoise, BoundError

DEG = math.pi / 180.0


SLICINGS = slicings(slices.run_in_slices)


def mixed_path():
    """Dwells that straddle slice boundaries, moves inside one step and across several, a triangular profile."""
    mv = (Move("outer", 90 * DEG, 10 * DEG, 13.3), Move("inner", 180 * DEG, 10 * DEG, 7.0),
          Move("outer", -45 * DEG, 5 * DEG, 21.0), Move("inner", 3 * DEG, 10 * DEG, 11.0),
          Move("outer", 270 * DEG, 10 * DEG, 17.0))
    return RotationPath("mixed", mv, accel=20 * DEG, initial_dwell=9.5, closed=False)


CASES = {
    "51 s16": (lambda: C.make_setup("51"), s16_table1),
    "unified (encoder rows)": (lambda: C.make_setup("unified"), mixed_path),
    "51 lever9 async at 2 Hz": (lambda: C.make_setup("51,lever9,async", filter_rate_hz=2.0), mixed_path),
    "30 with bias GM and RW at 0.2 Hz": (
        lambda: C.make_setup("30", filter_rate_hz=0.2, bias_noise=BiasNoise(gyro_gm=np.full(3, 1e-8), gyro_tau=600.0,
                                                                             accel_rw=np.full(3, 1e-7))), mixed_path),
}


@pytest.mark.parametrize("case", CASES)
def test_bound_does_not_depend_on_the_slicing(case, monkeypatch):
    make, path = CASES[case]
    setup, p = make(), path()
    monkeypatch.setattr(C, "run_in_slices", one_call)
    ref = C.evaluate(setup, p)
    assert ref.steps > 20
    for name, run in SLICINGS.items():
        monkeypatch.setattr(C, "run_in_slices", run)
        b = C.evaluate(setup, p)
        assert np.array_equal(b.covariance, ref.covariance), name
        assert np.array_equal(b.history, ref.history), name
        nh = C.evaluate(setup, p, keep_history=False)
        assert nh.history is None and np.array_equal(nh.covariance, ref.covariance), name


def factor_inputs(M=400, p=12, seed=3, att=True):
    rng = np.random.default_rng(seed)
    phinn = np.eye(9) + 0.02 * rng.normal(size=(M, 9, 9))
    phinp = 0.1 * rng.normal(size=(M, 9, p))
    r = rng.uniform(0.5, 2.0, 6)
    if not att:
        return phinn, phinp, r
    W = rng.normal(size=(M, 3, 9 + p))
    used = (rng.random(M) < 0.6).astype(np.int8)
    return phinn, phinp, r, W, used


@pytest.mark.parametrize("att", [False, True], ids=["velocity and position rows", "with encoder rows"])
def test_observability_factor_does_not_depend_on_the_slicing(att, monkeypatch):
    args = factor_inputs(att=att)
    monkeypatch.setattr(O, "run_in_slices", one_call)
    R0, g0 = O._triangular_factor(*args)
    assert g0 > 1.0
    for name, run in SLICINGS.items():
        monkeypatch.setattr(O, "run_in_slices", run)
        R, g = O._triangular_factor(*args)
        assert np.array_equal(R, R0) and g == g0, name


def test_run_in_slices_covers_every_step_once_in_order():
    seen = []
    calls = slices.run_in_slices(1000, lambda k0, k1: seen.append((k0, k1)), first=3, target_s=1e-3)
    assert calls == len(seen) > 1
    assert seen[0] == (0, 3) and seen[-1][1] == 1000
    assert all(a[1] == b[0] and b[1] > b[0] for a, b in itertools.pairwise(seen))
    assert slices.run_in_slices(0, lambda k0, k1: seen.append(None)) == 0


def test_run_in_slices_stops_at_a_pending_interrupt(monkeypatch):
    """A cancellation (the SIGINT/SIGTERM handler's, which Python may have had to drop) is raised
    after the slice in progress, never after the whole loop."""

    class Stop(BaseException):
        pass

    done = []

    def check():
        if len(done) >= 2:
            raise Stop

    monkeypatch.setattr(slices, "check_cancel", check)
    with pytest.raises(Stop):
        slices.run_in_slices(10**6, lambda k0, k1: done.append(k1), first=10)
    assert len(done) == 2 and done[-1] < 10**6


def test_slices_stay_short_for_slow_steps():
    """A slow kernel (1 ms a step) is called with slices of about SLICE_S, not with all its steps."""
    sizes = []

    def slow(k0, k1):
        sizes.append(k1 - k0)
        time.sleep(1e-3 * (k1 - k0))

    slices.run_in_slices(400, slow, first=256)
    assert max(sizes[1:]) <= 4 * slices.SLICE_S / 1e-3


def test_bound_refuses_an_absurd_number_of_steps_before_allocating():
    setup = C.make_setup("51", filter_rate_hz=1e6)
    assert C.bound_steps(s16_table1().duration, 1e6) > C.MAX_STEPS
    with pytest.raises(BoundError, match="more than the 1e\\+07 of a sensible bound"):
        C.evaluate(setup, s16_table1())


def test_bound_steps_counts_as_evaluate():
    setup = C.make_setup("30", filter_rate_hz=3.0)
    p = mixed_path()
    assert C.bound_steps(p.duration, 3.0) == C.evaluate(setup, p, keep_history=False).steps
    assert C.bound_bytes(setup, 1000, keep_history=False) == 0
    assert C.bound_bytes(setup, 1000) == 8 * 1000 * (setup.sig.size + setup.n_params)
