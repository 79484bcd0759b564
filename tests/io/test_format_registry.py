"""The format table (:data:`inscal.io.formats.REGISTRY`): every row's plugin module reads, the importer's
option checks and the mapping follow the rows, the table costs the command line's start no NumPy, and
one record loader (:func:`inscal.io.recordfile.load_record`) refuses a malformed record in one line for the
command line and the lab alike."""

from __future__ import annotations

import math
import subprocess
import sys

import h5py
import numpy as np
import pytest

from inscal import io
from inscal.core.earth import Site
from inscal.io import importers
from inscal.io.formats import REGISTRY, export_formats, format_spec, reader, taking, with_mapping
from inscal.io.mapping import EXPORT_FORMATS, FORMATS, ImportFileError, parse_mapping

SITE = Site(math.radians(30.0), math.radians(120.0), 10.0)


def test_every_row_names_a_module_with_a_reader():
    for name, spec in REGISTRY.items():
        mod = reader(spec)
        assert callable(mod.read) and (not spec.exports or callable(mod.write)), name
        assert spec.mapping in ("columns", "site") and set(spec.options) <= {
            "dtype", "variable", "rates", "topic", "stamps", "temperature_topic", "config"}, name
    assert FORMATS == tuple(REGISTRY) and set(EXPORT_FORMATS) == set(export_formats()) == {"csv", "psins", "mat",
                                                                                          "kf-gins"}
    with pytest.raises(ValueError, match="choose one of: psins, psins-imu"):
        format_spec("xls")
    with pytest.raises(ValueError, match="unknown export format 'txt'"):
        format_spec("txt", export=True)


def test_the_importer_refuses_an_option_the_row_does_not_take(tmp_path):
    src = tmp_path / "imu.txt"
    src.write_text("0.01 0 0 0 0 0 0.098\n0.02 0 0 0 0 0 0.098\n")
    assert taking("rates") == ("psins", "mat")
    for fmt in [f for f in REGISTRY if f not in taking("rates")]:  # refused before the source is read
        with pytest.raises(ImportFileError, match="--rates applies to psins/mat; for csv/txt set kind"):
            importers.import_file(src, tmp_path / "o.h5", fmt, SITE, rates=True)
    with pytest.raises(ImportFileError, match="--dtype applies to --format psins"):
        importers.import_file(src, tmp_path / "o.h5", "mat", SITE, dtype="float32")
    with pytest.raises(ImportFileError, match="--topic, --stamps and --temperature-topic apply to --format rosbag"):
        importers.import_file(src, tmp_path / "o.h5", "kf-gins", SITE, topic="/imu")
    # a site-only format's mapping holds [site] alone; a columns format's mapping needs its columns
    with pytest.raises(ImportFileError, match=r"apply to --format csv\|txt; a mat mapping may only hold \[site\]"):
        parse_mapping({"kind": "rates"}, "mat")
    assert with_mapping("columns") == ("csv", "txt")
    cols = {"columns": {c: k for k, c in enumerate(("gx", "gy", "gz", "ax", "ay", "az"))},
            "units": {"gyro": "rad", "accel": "m/s"}}
    assert parse_mapping(cols, "csv")[0].delimiter == "," and parse_mapping(cols, "txt")[0].delimiter is None
    assert not (tmp_path / "o.h5").exists()


def test_the_site_options_complete_the_mapping_site():
    base = Site(math.radians(34.0), math.radians(108.9), 380.0)
    s = importers.site_from_options(None, None, 12.0, base)
    assert (s.latitude, s.longitude, s.height) == (base.latitude, base.longitude, 12.0)
    assert importers.site_from_options(None, None, None, base) is None
    with pytest.raises(ImportFileError, match=r"give --lat, --lon and --height together \(missing --lon, --height\)"):
        importers.site_from_options(30.0, None, None, None)
    with pytest.raises(ImportFileError, match="--height must be finite"):
        importers.site_from_options(30.0, 120.0, math.inf, None)


def test_the_table_costs_the_command_line_no_numpy():
    code = ("import sys; import inscal.cli.app; from inscal.io.formats import REGISTRY; "
            "print(sorted(m for m in ('numpy', 'h5py', 'inscal.io.records', 'inscal.io.recordfile', "
            "'inscal.io.streaming') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out


def test_one_loader_refuses_integer_increments_for_the_cli_and_the_lab(tmp_path):
    from inscal.cli.common import CliError, read_record
    from inscal.runs.calibration import load_record

    n = 50
    t = np.arange(1, n + 1) * 0.01
    path = tmp_path / "r.h5"
    io.write_record(path, io.Record(t, np.zeros((n, 3)), np.tile([0.0, 0.0, 0.098], (n, 1)), None, 100.0, SITE))
    assert load_record(path).dtheta.dtype == np.float64
    with h5py.File(path, "r+") as h5:
        del h5["dtheta"]
        h5["dtheta"] = np.zeros((n, 3), dtype=np.int32)
    with pytest.raises(io.DataFileError) as lab_err:
        load_record(path)
    with pytest.raises(CliError) as cli_err:
        read_record(path)
    assert str(lab_err.value) == str(cli_err.value) and "must be floating point" in str(cli_err.value)
    assert str(cli_err.value).count("\n") == 0 and "int32" in str(cli_err.value)
