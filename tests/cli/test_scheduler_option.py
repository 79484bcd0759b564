"""``--scheduler`` of ``design`` and ``montecarlo``: a value that is neither a keyword nor a Dask address
is one line (exit 2), not a ValueError traceback from inside Dask; nothing is written."""

import pytest
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.cli.common import CliError, check_scheduler


@pytest.mark.parametrize("value", ["not an address", "nohostport", "tcp://host:notaport", "ftp://host:1",
                                   "host:70000", ":8786"])
def test_bad_addresses_are_refused(value):
    with pytest.raises(CliError, match="not a Dask scheduler address"):
        check_scheduler(value, ("local",))


@pytest.mark.parametrize("value", [None, "local", "tcp://10.0.0.5:8786", "127.0.0.1:8786", "tls://h.example:443",
                                   "inproc://a:1"])
def test_good_values_pass(value):
    assert check_scheduler(value, ("local",)) == value


@pytest.mark.parametrize("args", [["design", "--minutes", "10"], ["montecarlo", "fig5", "--runs", "2"]])
def test_cli_one_line_and_nothing_written(tmp_path, args):
    out = tmp_path / ("d.toml" if args[0] == "design" else "mc")
    r = CliRunner().invoke(app, args + ["--out", str(out), "--scheduler", "not an address"])
    assert r.exit_code == 2 and r.stderr.count("\n") == 1 and "not a Dask scheduler address" in r.stderr, r.output
    assert not out.exists()
