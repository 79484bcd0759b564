"""Monte Carlo framework: seeds, resume, refusal, outputs, Dask, CLI, built-in experiments."""

from __future__ import annotations

import json
import math
import os
import re
import sys

import numpy as np
import pytest

from inscal.analysis import montecarlo as mc
from inscal.analysis import studies
from inscal.cli.montecarlo import format_cell, format_table
from inscal.core.parallel import start_client
from inscal.core.progress import duration


# ------------------------------------------------------------------ a small dummy experiment
def _dummy_run(exp, p, rng):
    mu = exp.points[p]["mu"]
    x = rng.normal(mu, exp.params["sigma"], size=4)
    if exp.params.get("fail_above") is not None and x[0] > exp.params["fail_above"]:
        raise RuntimeError("draw too large")
    # the worker's allocator setting (Dask's nanny sets it unless the runner takes it out)
    return {"x": float(x.mean()), "first": float(x[0]), "malloc_trim": os.environ.get("MALLOC_TRIM_THRESHOLD_")}


def _dummy_summarize(exp, results):
    rows = []
    for pt, res in zip(exp.points, results):
        x = np.array([r["x"] for r in res])
        rows.append({"mu": pt["mu"], "n": len(res), "mean": float(x.mean()) if len(x) else None,
                     "std": float(x.std(ddof=1)) if len(x) > 1 else None})
    return mc.Summary("dummy", [("mu", "mu"), ("n", "n"), ("mean", "mean"), ("std", "std")], rows)


def _dummy_plot(exp, s, path):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([r["mu"] for r in s.rows], [r["mean"] for r in s.rows], "o")
    fig.savefig(path)


def dummy(mus=(0.0, 1.0, 5.0), sigma=1.0, fail_above=None):
    return mc.Experiment("dummy", {"mus": list(mus), "sigma": sigma, "fail_above": fail_above},
                         tuple({"mu": float(m)} for m in mus), _dummy_run, _dummy_summarize, _dummy_plot)


studies.register_experiment("test-dummy", dummy, "test only")


def results_of(res: mc.StudyResult) -> dict:
    return {rid: rec.get("result", rec.get("error")) for rid, rec in res.records.items()}


# ----------------------------------------------------------------------------------- seeds
def test_seed_mapping_is_spawn_and_independent_of_total():
    ch = mc.seed_children(42, 10)
    big = mc.seed_children(42, 1000)
    for i in (0, 3, 9):
        assert ch[i].spawn_key == (i,)
        assert np.array_equal(ch[i].generate_state(4), big[i].generate_state(4))
        assert np.array_equal(ch[i].generate_state(4), np.random.SeedSequence(42, spawn_key=(i,)).generate_state(4))
    assert not np.array_equal(ch[0].generate_state(4), ch[1].generate_state(4))
    assert mc.run_layout(3, 2) == [(0, 0, 0), (1, 1, 0), (2, 2, 0), (3, 0, 1), (4, 1, 1), (5, 2, 1)]


def test_run_uses_its_child_seed(tmp_path):
    exp = dummy()
    res = mc.run_study(exp, tmp_path / "a", runs=4, seed=7, scheduler="synchronous")
    ch = np.random.SeedSequence(7).spawn(12)
    for rid, p, r in mc.run_layout(3, 4):
        expect = _dummy_run(exp, p, np.random.default_rng(ch[rid]))
        assert res.records[rid]["result"] == expect
        assert (res.records[rid]["point"], res.records[rid]["rep"]) == (p, r)


def test_results_do_not_depend_on_runs_batching_or_seed_change(tmp_path):
    exp = dummy()
    a = mc.run_study(exp, tmp_path / "a", runs=3, seed=1, scheduler="synchronous")
    b = mc.run_study(exp, tmp_path / "b", runs=6, seed=1, scheduler="synchronous")
    assert all(results_of(b)[k] == v for k, v in results_of(a).items())  # extending keeps runs
    c = mc.run_study(exp, tmp_path / "c", runs=3, seed=2, scheduler="synchronous")
    assert results_of(c) != results_of(a)
    # extend a study in place: the first runs are kept, the new ones equal b's
    a2 = mc.run_study(exp, tmp_path / "a", runs=6, seed=1, scheduler="synchronous")
    assert a2.n_new == 9 and results_of(a2) == results_of(b)


# ---------------------------------------------------------------------------------- resume
def test_resume_after_interruption_gives_identical_results(tmp_path):
    exp = dummy()
    full = mc.run_study(exp, tmp_path / "full", runs=10, seed=3, scheduler="synchronous")
    part = mc.run_study(exp, tmp_path / "part", runs=10, seed=3, scheduler="synchronous", max_new_runs=7)
    assert part.stopped_early and not part.complete() and len(part.records) == 7
    # the file really holds 7 runs after the "interruption"
    header, recs = mc.read_results(tmp_path / "part" / mc.RUNS_FILE)
    assert len(recs) == 7 and header["seed"] == 3
    rest = mc.run_study(exp, tmp_path / "part", runs=10, seed=3, scheduler="synchronous")
    assert rest.n_new == 23 and rest.complete()
    assert results_of(rest) == results_of(full)
    s_full = mc.summarize(exp, full).to_dict()
    s_rest = mc.summarize(exp, rest).to_dict()
    s_full["data"].pop("run_seconds_total")
    s_rest["data"].pop("run_seconds_total")
    assert s_full == s_rest
    # a finished study reruns nothing
    again = mc.run_study(exp, tmp_path / "part", runs=10, seed=3, scheduler="synchronous")
    assert again.n_new == 0


def test_truncated_last_line_is_dropped_and_rerun(tmp_path):
    exp = dummy()
    ref = mc.run_study(exp, tmp_path / "ref", runs=2, seed=0, scheduler="synchronous")
    mc.run_study(exp, tmp_path / "x", runs=2, seed=0, scheduler="synchronous", max_new_runs=4)
    f = tmp_path / "x" / mc.RUNS_FILE
    raw = f.read_bytes()
    f.write_bytes(raw[:-15])  # a writer killed in the middle of the 4th record
    h, recs = mc.read_results(f)
    assert len(recs) == 3
    res = mc.run_study(exp, tmp_path / "x", runs=2, seed=0, scheduler="synchronous")
    assert res.n_new == 3 and results_of(res) == results_of(ref)
    lines = f.read_text().splitlines()
    assert len(lines) == 1 + 6 and all(json.loads(line) for line in lines)


def test_damaged_middle_line_is_an_error(tmp_path):
    mc.run_study(dummy(), tmp_path, runs=2, seed=0, scheduler="synchronous")
    f = tmp_path / mc.RUNS_FILE
    lines = f.read_text().splitlines()
    lines[2] = lines[2][:10]
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(mc.StudyError, match="line 3"):
        mc.run_study(dummy(), tmp_path, runs=2, seed=0, scheduler="synchronous")


# ------------------------------------------------------------------------------ refusal
def test_mismatched_study_is_refused_unless_forced(tmp_path):
    mc.run_study(dummy(), tmp_path, runs=2, seed=0, scheduler="synchronous")
    with pytest.raises(mc.StudyError, match=r"params.sigma \(1.0 here, 2.0 asked\)"):
        mc.run_study(dummy(sigma=2.0), tmp_path, runs=2, seed=0, scheduler="synchronous")
    with pytest.raises(mc.StudyError, match="seed"):
        mc.run_study(dummy(), tmp_path, runs=2, seed=1, scheduler="synchronous")
    other = mc.Experiment("other", {"mus": [0.0, 1.0, 5.0], "sigma": 1.0, "fail_above": None},
                          dummy().points, _dummy_run, _dummy_summarize)
    with pytest.raises(mc.StudyError, match="experiment"):
        mc.run_study(other, tmp_path, runs=2, seed=0, scheduler="synchronous")
    # nothing was appended by the refused calls
    assert len(mc.read_results(tmp_path / mc.RUNS_FILE)[1]) == 6
    res = mc.run_study(dummy(sigma=2.0), tmp_path, runs=2, seed=0, scheduler="synchronous", force=True)
    assert res.n_new == 6 and res.header["params"]["sigma"] == 2.0


def test_bad_arguments(tmp_path):
    with pytest.raises(mc.StudyError):
        mc.run_study(dummy(), tmp_path, runs=0, scheduler="synchronous")
    with pytest.raises(mc.StudyError):
        mc.run_study(dummy(), tmp_path, runs=1, seed=-1, scheduler="synchronous")
    with pytest.raises(mc.StudyError, match="unknown experiment"):
        studies.get_experiment("nope")
    with pytest.raises(mc.StudyError):
        studies.get_experiment("n25-fig5", {"dtheta_arcsec": [1, 1]})
    with pytest.raises(mc.StudyError):
        studies.get_experiment("n25-fig5", {"no_such_param": 1})
    with pytest.raises(mc.StudyError):
        studies.get_experiment("n25-schemes", {"simulation": "fast"})


# ------------------------------------------------------------------- failures and outputs
def test_failed_runs_are_recorded_and_reported(tmp_path):
    exp = dummy(mus=(0.0,), fail_above=0.5)
    res = mc.run_study(exp, tmp_path, runs=40, seed=0, scheduler="synchronous")
    errs = [r for r in res.records.values() if "error" in r]
    assert 0 < len(errs) < 40 and errs[0]["error"] == "RuntimeError: draw too large"
    s = mc.summarize(exp, res)
    assert s.rows[0]["n"] == 40 - len(errs)
    assert s.data["runs_failed"] == [len(errs)]
    assert any("failed" in n for n in s.notes)


def test_outputs_written(tmp_path):
    exp = dummy()
    res = mc.run_study(exp, tmp_path, runs=5, seed=0, scheduler="synchronous")
    s = mc.summarize(exp, res)
    paths = mc.write_outputs(exp, s, tmp_path)
    d = json.loads(paths["json"].read_text())
    assert d["rows"][2]["mu"] == 5.0 and d["data"]["runs_per_point"] == 5
    assert paths["csv"].read_text().splitlines()[0] == "mu,n,mean,std"
    assert paths["png"].read_bytes()[:4] == b"\x89PNG"


def test_load_study_from_folder(tmp_path):
    exp = studies.get_experiment("test-dummy", {"sigma": 0.5})
    mc.run_study(exp, tmp_path, runs=3, seed=9, scheduler="synchronous")
    exp2, res2 = studies.load_study(tmp_path)
    assert exp2.params == exp.params and res2.runs == 3 and res2.complete()


# ------------------------------------------------------------------------------------ Dask
@pytest.fixture(scope="module")
def _local_clusters():
    started: list = []
    yield started
    for cluster, _ in started:
        cluster.close()


@pytest.fixture()
def one_local_cluster(_local_clusters, monkeypatch):
    """The tests of the runner's own LocalCluster (``workers=2``) share one (its two worker processes start
    in ~5 s of CPU): the first ``run_study`` starts it through the runner's ``start_client`` call, the later
    ones, with the same arguments, get a client of it; it closes with the module."""

    def shared(scheduler, workers, *args):
        from distributed import Client

        if not _local_clusters:
            client, cluster = start_client(scheduler, workers, *args)
            _local_clusters.append((cluster, (scheduler, workers, *args)))
            return client, None
        assert (scheduler, workers, *args) == _local_clusters[0][1]
        return Client(_local_clusters[0][0]), None

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    monkeypatch.setattr(mc, "start_client", shared)


def test_local_cluster_two_workers_matches_synchronous(tmp_path, monkeypatch, one_local_cluster):
    """Same results as in this process; and the workers keep glibc's default allocator (Dask's
    MALLOC_TRIM_THRESHOLD_ made every run of n25-fig5 1.6x slower there)."""
    pytest.importorskip("distributed")
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the dummy lives in this test module
    exp = dummy()
    sync = mc.run_study(exp, tmp_path / "s", runs=6, seed=5, scheduler="synchronous")
    dask_ = mc.run_study(exp, tmp_path / "d", runs=6, seed=5, workers=2, batch_size=2)
    assert dask_.n_new == 18 and dask_.complete()
    assert results_of(dask_) == results_of(sync)
    assert {r["malloc_trim"] for r in results_of(dask_).values()} == {None}
    # run order in the file may differ, content per run may not
    _, recs = mc.read_results(tmp_path / "d" / mc.RUNS_FILE)
    assert sorted(recs) == list(range(18))


def test_make_batches_groups_points_and_interleaves():
    items = [(rid, p, r, None) for rid, p, r in mc.run_layout(2, 5)]
    b = mc.make_batches(items, 2)
    assert [len(x) for x in b] == [2, 2, 2, 2, 1, 1]
    assert all(len({it[1] for it in x}) == 1 for x in b)
    assert [x[0][1] for x in b] == [0, 1, 0, 1, 0, 1]
    assert sorted(it[0] for x in b for it in x) == list(range(10))


# ------------------------------------------------------------------------------------- CLI
def test_cli_run_resume_json_and_refusal(tmp_path):
    from typer.testing import CliRunner

    from inscal.cli.app import app

    r = CliRunner()
    out = tmp_path / "study"
    res = r.invoke(app, ["montecarlo", "test-dummy", "--runs", "4", "--out", str(out), "--no-dask", "--json", "--seed", "2"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.stdout)
    assert d["complete"] and d["new_runs"] == 12 and len(d["rows"]) == 3
    assert (out / "summary.png").exists() and (out / "summary.csv").exists()
    res = r.invoke(app, ["montecarlo", "test-dummy", "--runs", "4", "--out", str(out), "--no-dask", "--json", "--seed", "2"])
    assert res.exit_code == 0 and json.loads(res.stdout)["new_runs"] == 0
    res = r.invoke(app, ["montecarlo", "test-dummy", "--runs", "4", "--out", str(out), "--no-dask", "--set", "sigma=3"])
    assert res.exit_code == 2 and "different study" in res.output and "--force" in res.output
    res = r.invoke(app, ["montecarlo", "test-dummy", "--runs", "2", "--out", str(out), "--no-dask", "--set", "sigma=3", "--force",
                         "--no-progress"])
    assert res.exit_code == 0, res.output
    assert "dummy" in res.stdout
    res = r.invoke(app, ["montecarlo", "test-dummy", "--runs", "2", "--out", str(out), "--no-dask", "--set", "oops"])
    assert res.exit_code == 2 and "KEY=VALUE" in res.output
    res = r.invoke(app, ["montecarlo", "--list"])
    assert res.exit_code == 0 and all(n in res.stdout for n in ("n25-fig5", "n25-schemes", "s16-table2"))


# ------------------------------------------------------------------ built-in experiments
def test_reuse_simulation_is_bit_identical_to_full():
    from inscal.analysis.studies import common as E

    exp = studies.get_experiment("n25-fig5", {"dtheta_arcsec": [7.0]})
    key = E.scenario_key(exp.params, 7.0)
    full = E.simulate_record(key, np.random.default_rng(np.random.SeedSequence(11)), "full")
    fast = E.simulate_record(key, np.random.default_rng(np.random.SeedSequence(11)), "reuse")
    for name in ("time", "dtheta", "dvel", "gimbal"):
        assert np.array_equal(getattr(full, name), getattr(fast, name)), name
    other = E.simulate_record(key, np.random.default_rng(np.random.SeedSequence(12)), "reuse")
    assert not np.array_equal(other.dtheta, fast.dtheta)
    sc = E.n25_scenario(exp.params, 7.0)
    assert math.isclose(sc.gimbal.nonorthogonality, 7.0 * math.pi / 180 / 3600)
    assert full.dtheta.shape[0] == sc.n_samples


def test_parameter_errors_field_units():
    from inscal.analysis.truth import parameter_errors
    from inscal.core.error_model import GimbalErrors, ImuErrors

    t = ImuErrors()
    e = ImuErrors(accel_bias=[0, 0, 9.80665e-5])  # 10 ug on z
    g0, g1 = GimbalErrors(), GimbalErrors(math.pi / 180 / 3600, [0, 0, 0])
    d = parameter_errors(e, g1, t, g0, ["accel_bias", "gimbal_nonorthogonality", "accel_misalignment"])
    assert d["accel_bias.z"] == pytest.approx(10.0, rel=1e-3) and d["accel_bias.x"] == 0
    assert d["gimbal_nonorthogonality"] == pytest.approx(1.0)
    assert set(k for k in d if k.startswith("accel_misalignment")) == {f"accel_misalignment.{c}" for c in ("xy", "xz", "yx", "yz", "zx", "zy")}


def test_a_running_study_locks_its_folder(tmp_path):
    with mc._FolderLock(tmp_path):
        with pytest.raises(mc.StudyError, match="in use"):
            mc.run_study(dummy(), tmp_path, runs=1, scheduler="synchronous")
    assert mc.run_study(dummy(), tmp_path, runs=1, scheduler="synchronous").n_new == 3


def test_failed_runs_are_retried_on_resume_and_broken_setups_stop(tmp_path):
    exp = dummy(mus=(0.0,), fail_above=0.5)
    first = mc.run_study(exp, tmp_path, runs=40, seed=0, scheduler="synchronous")
    n_err = sum("error" in r for r in first.records.values())
    again = mc.run_study(exp, tmp_path, runs=40, seed=0, scheduler="synchronous")
    assert again.n_new == n_err  # deterministic failures: retried, fail again
    assert sum("error" in r for r in again.records.values()) == n_err
    # every run fails: the study stops after FAIL_FAST_RUNS runs instead of running all
    with pytest.raises(mc.StudyError, match="all failed"):
        mc.run_study(dummy(mus=(0.0,), fail_above=-100.0), tmp_path / "b", runs=100, scheduler="synchronous")
    assert len(mc.read_results(tmp_path / "b" / mc.RUNS_FILE)[1]) == mc.FAIL_FAST_RUNS


def test_small_n25_fig5_rsd_decreases_with_dtheta(tmp_path):
    pytest.importorskip("inscal.calibrate")
    exp = studies.get_experiment("n25-fig5", {"dtheta_arcsec": [2.0, 7.0, 30.0], "simulation": "reuse"})
    res = mc.run_study(exp, tmp_path, runs=10, seed=0, scheduler="synchronous")
    s = mc.summarize(exp, res)
    rows = s.rows
    assert [r["n"] for r in rows] == [10, 10, 10]
    rsd = [r["rsd_pct"] for r in rows]
    assert rsd[0] > rsd[1] > rsd[2] > 0
    for r in rows:
        # the estimation noise does not depend on dtheta much, and the estimate is unbiased
        assert 0.02 < r["std_arcsec"] < 2.0
        assert abs(r["bias_arcsec"]) < 4 * r["std_arcsec"] / math.sqrt(r["n"]) + 0.05
        assert r["rsd_ci95_lo_pct"] < r["rsd_pct"] < r["rsd_ci95_hi_pct"]
    assert s.data["rsd_below_threshold"] is True and "yes" in s.notes[0]
    paths = mc.write_outputs(exp, s, tmp_path)
    assert paths["png"].stat().st_size > 1000


def test_n25_fig5_with_one_run_per_value_draws_and_gives_no_verdict(tmp_path):
    """One run per dθ value has no spread: the summary says the verdict is not known (not NO) and the
    plot says why instead of failing on log axes of nothing."""
    exp = studies.get_experiment("n25-fig5", {"dtheta_arcsec": [7.0, 30.0], "simulation": "reuse"})
    res = mc.run_study(exp, tmp_path, runs=1, seed=0, scheduler="synchronous")
    s = mc.summarize(exp, res)
    assert s.data["rsd_below_threshold"] is None and "not known" in s.notes[0]
    paths = mc.write_outputs(exp, s, tmp_path)
    assert paths["png"].stat().st_size > 1000


@pytest.mark.slow
def test_small_n25_schemes_shows_the_n25_claims(tmp_path):
    pytest.importorskip("inscal.calibrate")
    exp = studies.get_experiment("n25-schemes", {"simulation": "reuse"})
    assert exp.params["methods"] == ["n25", "six-position", "joint", "systematic30"]  # scheme 3 by default
    res = mc.run_study(exp, tmp_path, runs=3, seed=1, scheduler="synchronous")
    s = mc.summarize(exp, res)
    rows = {r["parameter"]: r for r in s.rows}
    assert "accel_bias.z" in rows and "gimbal_nonorthogonality" in rows
    row = rows["gimbal_nonorthogonality"]
    assert row["six-position_bias"] is None and row["n25_std"] > 0  # six-position does not estimate dtheta
    # scheme 3: the gimbal and the 3 gyro angles that define its frame are absent, not zero errors
    assert row["systematic30_bias"] is None and rows["mount_attitude.gamma0"]["systematic30_rms"] is None
    for c in ("xy", "xz", "yz"):
        assert rows[f"gyro_misalignment.{c}"]["systematic30_rms"] is None
        assert rows[f"accel_misalignment.{c}"]["systematic30_rms"] is not None
    # its errors are taken against the truth mapped into the gyro-defined frame: without that
    # mapping the accelerometer angles would be off by the gyro angles of the truth (10-25")
    for k in ("accel_misalignment.xy", "accel_misalignment.yz", "accel_misalignment.zy", "gyro_misalignment.zy"):
        assert rows[k]["systematic30_rms"] < 3.0, k
    for k in ("accel_bias.x", "accel_bias.y", "accel_bias.z"):
        assert rows[k]["systematic30_rms"] < 3.0, k  # ug; six-position is off by hundreds
    diag = s.data["scheme3_diagnostics"]["systematic30"]
    assert diag["runs"] == 3 and 4.0 < diag["nis_mean"] < 8.0
    checks = {c["claim"]: c for c in s.data["checks"]}
    assert len(checks) == 9
    for claim, c in checks.items():
        if claim.startswith("n25 < six-position"):
            assert c["holds"], claim  # systematic (leveling, dtheta) errors: clear even with 3 runs
    s3 = [c for k, c in checks.items() if k.startswith("n25 < systematic30")]
    assert len(s3) == 3 and all(math.isfinite(c["systematic30"]) and c["systematic30"] > 0 for c in s3)
    ratios = next(c for k, c in checks.items() if k.startswith("scheme 3"))["ratios"]
    assert set(ratios) == {"gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor",
                           "accel_misalignment", "accel_bias"}
    assert any("scheme 3 (systematic30" in n for n in s.notes)
    assert mc.write_outputs(exp, s, tmp_path)["png"].exists()


def test_result_errors_map_the_truth_and_drop_frame_fixed_components():
    from inscal.analysis.truth import result_errors
    from inscal.calibrate.result import CalibrationResult
    from inscal.core.error_model import GimbalErrors, ImuErrors

    arcsec = math.pi / 180 / 3600
    true = ImuErrors(gyro_misalignment=[5 * arcsec, 0, 0, 0, 0, 0], accel_bias=[0, 0, 9.80665e-5])
    est = ImuErrors(accel_bias=[0, 0, 2 * 9.80665e-5])  # estimate in a frame where the truth has no gyro angle
    sig = {"gyro_misalignment": np.array([np.nan, np.nan, 1.0, np.nan, 1.0, 1.0]) * arcsec,
           "accel_bias": np.full(3, 9.80665e-6)}
    res = CalibrationResult("x", est, GimbalErrors(), sig, ("gyro_misalignment", "accel_bias"))
    err, s = result_errors(res, true, GimbalErrors(0.1, [0, 0, 0]))
    assert err["gyro_misalignment.xy"] == pytest.approx(-5.0)  # no transform: plain difference, all components
    assert set(s) == {"gyro_misalignment.yx", "gyro_misalignment.zx", "gyro_misalignment.zy", "accel_bias.x",
                      "accel_bias.y", "accel_bias.z"}
    assert not any(k.startswith("gimbal") or k.startswith("mount") for k in err)  # not estimated: absent
    res.truth_transform = lambda t: (ImuErrors(accel_bias=t[0].accel_bias), GimbalErrors())
    err, s = result_errors(res, true, GimbalErrors(0.1, [0, 0, 0]))
    assert set(err) == set(s) == {"gyro_misalignment.yx", "gyro_misalignment.zx", "gyro_misalignment.zy",
                                  "accel_bias.x", "accel_bias.y", "accel_bias.z"}  # frame-fixed angles dropped
    assert err["accel_bias.z"] == pytest.approx(10.0, rel=1e-9) and s["accel_bias.z"] == pytest.approx(1.0)
    assert err["gyro_misalignment.yx"] == 0.0


@pytest.mark.slow
def test_cli_s16_table2_small(tmp_path):
    """``inscal montecarlo s16-table2`` end to end (1 run, 50 Hz, two passes: the plumbing, not the figures)."""
    from typer.testing import CliRunner

    from inscal.cli.app import app

    out = tmp_path / "t2"
    r = CliRunner().invoke(app, ["montecarlo", "s16-table2", "--runs", "1", "--out", str(out), "--no-dask", "--json",
                                 "--set", "rate_hz=50", "--set", "max_passes=2"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["complete"] and d["data"]["methods"] == ["systematic51", "systematic30"]
    rows = {x["group"]: x for x in d["rows"]}
    assert len(rows) == 10
    for g, target in {"gyro_g_sensitivity": 2e-4, "accel_nonlinearity": 1.3, "accel_cross_coupling": 1.5,
                      "accel_lever_arm": 0.01}.items():
        assert rows[g]["s16_target"] == target and rows[g]["systematic30_mae"] is None  # not in the 30-state model
        assert rows[g]["systematic51_mae"] > 0 and rows[g]["systematic51_crb"] > 0
        if g != "gyro_g_sensitivity":  # its diagonal is barely observable (sigma ~ the 0.001 deg/h/g truth)
            assert rows[g]["systematic51_mae"] < rows[g]["before"] / 100
    assert rows["accel_bias"]["systematic30_mae"] > 10 * rows["accel_bias"]["systematic51_mae"]  # S16's point
    assert rows["accel_lever_arm"]["before"] == pytest.approx(2.0) and rows["accel_nonlinearity"]["before"] == pytest.approx(300.0)
    nees = d["data"]["nees"]["systematic51"]
    assert nees["dof"] == 42 and nees["runs"] == 1 and nees["mean"] > 0
    assert len(d["data"]["z"]["systematic51"]["components"]) == 42
    assert (out / "summary.png").stat().st_size > 5000 and (out / "summary.csv").exists()


def test_local_cluster_runs_the_real_experiment_identically(tmp_path, one_local_cluster):
    pytest.importorskip("inscal.calibrate")
    exp = studies.get_experiment("n25-fig5", {"dtheta_arcsec": [5.0, 20.0], "simulation": "reuse"})
    sync = mc.run_study(exp, tmp_path / "s", runs=2, seed=4, scheduler="synchronous")
    dask_ = mc.run_study(exp, tmp_path / "d", runs=2, seed=4, workers=2, batch_size=1)
    assert dask_.complete() and not any("error" in r for r in dask_.records.values())
    assert results_of(dask_) == results_of(sync)


def test_progress_lines_when_stderr_is_not_a_terminal(tmp_path, capsys):
    mc.run_study(dummy(), tmp_path, runs=10, scheduler="synchronous", progress=True)
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("dummy: 30/30 runs (100 %)")
    assert 5 <= len(err) <= 11


@pytest.mark.filterwarnings("ignore:Port .* is already in use")
def test_existing_cluster_by_address(tmp_path, monkeypatch):
    distributed = pytest.importorskip("distributed")
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    exp = dummy(mus=(2.0,))
    ref = mc.run_study(exp, tmp_path / "s", runs=5, seed=8, scheduler="synchronous")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        res = mc.run_study(exp, tmp_path / "d", runs=5, seed=8, scheduler=cluster.scheduler_address)
    assert results_of(res) == results_of(ref)
    monkeypatch.setattr(mc, "CONNECT_TIMEOUT", "1s")
    with pytest.raises(mc.StudyError, match="cannot reach"):
        mc.run_study(exp, tmp_path / "e", runs=1, scheduler="tcp://127.0.0.1:9")


def test_worker_kernels_are_cached_on_disk():
    """Dask workers load compiled numba code instead of compiling: every kernel the
    experiments reach is ``cache=True``."""
    import importlib
    import pkgutil

    from numba.core.caching import NullCache
    from numba.core.registry import CPUDispatcher

    import inscal

    names = [m.name for m in pkgutil.walk_packages(inscal.__path__, "inscal.") if not m.name.startswith("inscal.cli")]
    found = 0
    for name in names:
        mod = importlib.import_module(name)
        for obj in vars(mod).values():
            if isinstance(obj, CPUDispatcher) and obj.__module__ == name:
                found += 1
                assert not isinstance(obj._cache, NullCache), f"{name}.{obj.__name__} is not cache=True"
    assert found >= 3 and inscal.__version__


# ------------------------------------------------------------------ progress ETA and the table
def test_eta_is_mean_run_time_times_runs_left_over_workers(capsys):
    bar = mc._Progress(10, "eta", enabled=True, workers=2)  # stderr is not a terminal: plain lines
    assert bar.eta_s() is None
    bar.advance(2, 0, 6.0)  # 3 s per run so far
    assert bar.eta_s() == pytest.approx(3.0 * 8 / 2)
    bar.advance(3, 1, 3.0)  # 9 s over 5 runs
    assert bar.eta_s() == pytest.approx(9.0 / 5 * 5 / 2)
    bar.workers = 1
    assert bar.eta_s() == pytest.approx(9.0)
    bar.close()
    err = capsys.readouterr().err
    assert "about 12 s left (3 s per run, 2 workers)" in err and "1 failed" in err
    assert duration(42) == "42 s" and duration(185) == "3 min 05 s" and duration(7620) == "2 h 07 min"


def _wide_summary():
    rng = np.random.default_rng(3)
    methods = ["n25", "six-position", "joint", "systematic30"]
    cols = [("parameter", "parameter"), ("unit", "unit")]
    for m in methods:
        cols += [(f"{m}_bias", f"{m} bias"), (f"{m}_std", f"{m} std")]
    rows = []
    for name in ("gyro_scale_factor.x", "accel_misalignment.xy", "gimbal_nonorthogonality", "accel_bias.z"):
        row = {"parameter": name, "unit": "arcsec"}
        for m in methods:
            row[f"{m}_bias"] = float(rng.normal() * 10.0 ** rng.integers(-6, 5))
            row[f"{m}_std"] = float(abs(rng.normal()) * 10.0 ** rng.integers(-6, 5))
        rows.append(row)
    rows[0]["joint_bias"] = None
    rows[1]["n25_std"] = 123456.789
    return mc.Summary("n25-schemes: calibration error (estimate - truth), 200 runs, dθ = 20″", cols, rows,
                      ["a note long enough to wrap at eighty columns " * 3])


@pytest.mark.parametrize("columns", [80, 120])
def test_summary_table_fits_the_terminal_without_cutting_numbers(columns, monkeypatch):
    import io as _io

    monkeypatch.setenv("COLUMNS", str(columns))
    s = _wide_summary()
    buf = _io.StringIO()
    format_table(s, file=buf)
    text = buf.getvalue()
    assert "…" not in text
    assert max(len(line) for line in text.splitlines()) <= columns
    for row in s.rows:  # every number in full (3-4 significant digits), on one line
        for k, _ in s.columns:
            cell = format_cell(row.get(k))
            assert (k in ("parameter", "unit") or len(cell) <= 9) and re.search(
                rf"(^|\s){re.escape(cell)}(\s|$)", text, re.M), (k, cell)
    assert format_cell(123456.789) == "1.23e5" and format_cell(0.000968) == "0.000968" and format_cell(-1.234e-6) == "-1.23e-6" and format_cell(-0.07524) == "-0.07524"
    if columns == 80:
        assert "(part 2 of" in text  # split, with the parameter and unit repeated
        assert text.count("gimbal_nonorthogonality") >= 2


def test_cli_table_at_80_columns(tmp_path):
    from typer.testing import CliRunner

    from inscal.cli.app import app

    r = CliRunner().invoke(app, ["montecarlo", "test-dummy", "--runs", "3", "--out", str(tmp_path / "s"), "--no-dask"],
                           env={"COLUMNS": "80"})
    assert r.exit_code == 0, r.output
    assert "…" not in r.stdout and max(len(line) for line in r.stdout.splitlines()[:-1]) <= 80
