"""What the budget's command-line tests share: the test station, running ``inscal`` in-process and the
one-line refusal check (``tests/cli/test_*budget*_cli.py``; their two-window fixture is in conftest.py)."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from inscal.cli.app import app

runner = CliRunner()
#: the typical station of the budget's checks (2 arcsec table, 10 ppm rate, 1 arcsec wobble, 1 mGal)
STATION = Path(__file__).resolve().parents[1] / "data" / "station.toml"


def run(*args):
    """``inscal ARGS`` in this process (arguments as strings)."""
    return runner.invoke(app, [str(a) for a in args])


def one_line(r, *phrases):
    """``r`` refused with exit 2 and one line ``inscal: error: ...`` holding every phrase; that line."""
    assert r.exit_code == 2, (r.exit_code, r.stdout, r.stderr)
    err = r.stderr.strip()
    assert err.startswith("inscal: error: ") and "\n" not in err and "Traceback" not in err, err
    for p in phrases:
        assert p in err, (p, err)
    return err
