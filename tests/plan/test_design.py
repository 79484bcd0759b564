"""Path design from the Cramér-Rao bound: inscal.plan.design, ``inscal design``
and the path report (inscal.report.path)."""

import json
import math
import tomllib

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.plan import bound as C
from inscal.plan import design as D
from inscal.cli.app import app
from inscal.core.turntable import s16_table1
from inscal.core.units import DEG

runner = CliRunner()


def test_build_path_budget_and_limits():
    """Every candidate lasts exactly the budget, keeps the rate and angle limits (reversing a move that
    would leave them), and is reproducible from its seed."""
    lim = D.Limits(max_rate=8 * DEG, max_accel=5 * DEG, cable_wrap=200 * DEG, inner_range=(-90 * DEG, 100 * DEG))
    for seed in range(5):
        g = D.random_genes(np.random.default_rng(seed), lim)
        p, kept = D.build_path(g, 900.0, lim)
        assert p.duration == pytest.approx(900.0, abs=1e-6)
        assert p.accel == pytest.approx(5 * DEG) and all(m.rate <= 8 * DEG + 1e-12 for m in p.moves)
        assert all(m.dwell >= lim.min_dwell - 1e-9 for m in p.moves) and p.initial_dwell == lim.initial_dwell
        seg = p.segments()
        th, _, _ = seg.angles(np.linspace(0, p.duration, 5000))
        assert np.all(np.abs(th[:, 0]) <= 200 * DEG + 1e-9)
        assert np.all(th[:, 1] >= -90 * DEG - 1e-9) and np.all(th[:, 1] <= 100 * DEG + 1e-9)
        p2, _ = D.build_path(D.random_genes(np.random.default_rng(seed), lim), 900.0, lim)
        assert p2 == p
    only_inner = D.Limits(axes=("inner",))
    p, _ = D.build_path(D.random_genes(np.random.default_rng(0), only_inner), 600.0, only_inner)
    assert {m.axis for m in p.moves} == {"inner"}
    with pytest.raises(D.DesignError):
        D.build_path([(0, 90.0, 1.0, 1.0)], 61.0, D.Limits())
    with pytest.raises(D.DesignError):
        D.Limits(axes=("middle",))


def test_objectives_and_reference():
    """Targets = the bound of S16's own path: that path scores exactly 1 (worst-normalised and weighted);
    Table 2 targets replace its four groups."""
    su = C.make_setup("51")
    o = D.make_objective(su)
    assert o.value(o.reference) == pytest.approx(1.0)
    assert D.make_objective(su, "weighted").value(o.reference) == pytest.approx(1.0)
    t2 = D.make_objective(su, targets="s16-table2", groups="table2")
    assert t2.mask.sum() == 9 + 3 + 6 + 3
    k = su.labels.index("accel_lever_arm[x]")
    assert t2.targets[k] == pytest.approx(1e-4)  # 0.01 cm
    with pytest.raises(D.DesignError):
        D.make_objective(su, groups="no_such_group")
    with pytest.raises(D.DesignError):
        D.make_objective(su, "best-effort")


def test_search_improves_and_is_seeded():
    """In-process search: the best objective never gets worse over the generations, and a seed
    reproduces the result."""
    a = D.design(12, candidates=16, population=4, seed=5, scheduler="none")
    b = D.design(12, candidates=16, population=4, seed=5, scheduler="none")
    assert a.path == b.path and a.value == b.value
    assert all(y <= x + 1e-12 for x, y in zip(a.trace, a.trace[1:]))
    assert a.value <= a.trace[-1] + 1e-12 and a.trace[-1] == pytest.approx(a.objective.score(a.bound.sigma))
    assert a.path.duration == pytest.approx(720.0)
    assert a.evaluations == 16


def test_cli_design_round_trip(tmp_path):
    """The written file is a scenario (s16 base + designed [path]) that inscal simulate and
    observability accept, and its bound equals the reported one."""
    out = tmp_path / "designed.toml"
    png = tmp_path / "designed.png"
    r = runner.invoke(app, ["design", "--minutes", "10", "--candidates", "8", "--population", "4", "--seed", "2",
                            "--scheduler", "none", "--objective", "weighted", "--out", str(out), "--plot", str(png),
                            "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output[r.output.index("{"):])
    doc = tomllib.loads(out.read_text())
    assert doc["base"] == "s16" and doc["path"]["closed"] is False
    assert png.exists() and (tmp_path / "designed.html").read_text().startswith("<section")
    b = C.crlb(str(out))
    rep = {p["label"]: p["bound"] for p in d["bound"]["parameters"]}
    for row in b.table():
        assert row["bound"] == pytest.approx(rep[row["label"]], rel=1e-9)
    assert b.duration_s == pytest.approx(600.0)
    # the objective recomputed from the file's bound (its scenario's site, gimbal and noise)
    assert D.make_objective(b.setup, "weighted").value(b.sigma) == pytest.approx(d["objective"]["value"], rel=1e-9)
    r = runner.invoke(app, ["simulate", str(out), "--out", str(tmp_path / "rec.h5"), "--rate-hz", "10"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["observability", str(out), "--crlb"])
    assert r.exit_code == 0 and "designed" in r.output
    # no overwrite without --force
    r = runner.invoke(app, ["design", "--minutes", "10", "--candidates", "4", "--scheduler", "none",
                            "--out", str(out)])
    assert r.exit_code == 2 and "--force" in r.output


@pytest.mark.parametrize("bad", [
    ["--minutes", "-1"], ["--axes", "outer,middle"], ["--outer-range", "10,20"], ["--states", "nonsense"],
    ["--objective", "best"], ["--groups", "gyro_matrix,nope"], ["--candidates", "1"], ["--base", "nope"],
    ["--minutes", "1"], ["--cable-wrap", "10"],
])
def test_cli_design_bad_input(tmp_path, bad):
    r = runner.invoke(app, ["design", "--scheduler", "none", "--candidates", "4", "--out", str(tmp_path / "x.toml"),
                            *bad])
    assert r.exit_code == 2, r.output
    assert r.output.strip().count("\n") == 0 and r.output.startswith("inscal: error:"), r.output
    assert not (tmp_path / "x.toml").exists()


def test_path_report_gains():
    """Per-move gains: non-negative (a bound never grows for constants) and, summed over the moves, the
    total reduction of each group from prior to the final bound."""
    from inscal.report.path import group_history, move_gains

    p = s16_table1()
    b = C.evaluate(C.make_setup("51"), p)
    rows = move_gains(b, p)
    assert len(rows) == 19 and rows[0]["axis"] == "initial dwell"
    _, gh = group_history(b)
    for g, h in gh.items():
        total = sum(r["gain_decades"][g] for r in rows)
        assert total == pytest.approx(math.log10(h[0] / h[-1]), rel=1e-9)
        assert all(r["gain_decades"][g] >= -1e-9 for r in rows)
