"""Property tests of three text parsers a user hands inscal: the noise curve (``noise --from-curve``), the
station description (``--station FILE.toml``) and the import mapping (``import --mapping``).  Any text gives
a result or one line (the parser's own error), never another exception, in bounded time and memory; a
result keeps the parser's promises (a curve: at most its point limit, finite positive variances in their
range, whole increasing scales)."""

from __future__ import annotations

import math
import time
import tracemalloc

import numpy as np
import tomli_w
import tomllib
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from inscal.analysis.noise import identify as idf
from inscal.io.formats import ImportFileError
from inscal.io.mapping import load_mapping, parse_mapping
from inscal.uncertainty.station import StationError, read_station, station_from_dict

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.function_scoped_fixture])
#: what one parse may take (wall seconds, peak Python allocations)
TIME_S, PEAK_BYTES = 2.0, 64e6
STATION = tomllib.loads(open(__file__.replace("io/test_property_parsers.py", "data/station.toml")).read())


def bounded(fn, *args):
    """``fn(*args)`` -> (result, exception), checked for time and memory."""
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        out, exc = fn(*args), None
    except Exception as e:  # noqa: BLE001 - the caller checks the class
        out, exc = None, e
    elapsed = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert elapsed < TIME_S and peak < PEAK_BYTES, (elapsed, peak)
    return out, exc


def one_line(exc, cls):
    assert isinstance(exc, cls), repr(exc)
    assert "\n" not in str(exc) and str(exc).strip(), repr(str(exc))


number = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -1.0, 1e-302, 1e283, 1e-9]),
                   st.floats(1e-12, 1e3))
cell = st.one_of(number.map(repr), st.text(max_size=6), st.just(""))
row = st.lists(cell, min_size=0, max_size=6).map(",".join)
scales = st.lists(st.integers(1, 2 ** 40), unique=True, min_size=0, max_size=80).map(sorted)


@st.composite
def curve_text(draw):
    """Mostly well-formed curves (so that the result's promises are checked too), with defects drawn in."""
    rare = st.integers(0, 14).map(lambda k: k == 0)  # a defect one time in 15
    head = (draw(st.sampled_from(["tau,avar,lo,hi", ""])) if draw(rare) else
            draw(st.sampled_from(["tau_s,avar,lower,upper", "tau_s,adev,lower,upper", "tau_s,wvar,lower,upper"])))
    dt_lines = ["# dt_s = 0.01"] if not draw(rare) else draw(
        st.sampled_from([[], ["# dt_s = 0.01", "# dt_s = 0.02"], ["# dt_s"], ["# dt_s = x"]])
        | number.map(lambda x: [f"# dt_s = {x!r}"]))
    dt = 0.01
    lines = []
    for m in draw(scales):
        v = draw(number) if draw(rare) else draw(st.floats(1e-20, 1e-2))
        a, b = draw(st.floats(0.0, 1.0)), draw(st.floats(0.0, 2.0))
        lines.append(f"{m * dt!r},{v!r},{v * (1 - a / 2)!r},{v * (1 + b)!r}")
    if draw(rare):
        lines.insert(draw(st.integers(0, len(lines))), draw(row))
    if draw(st.integers(0, 9)) == 0:
        lines = draw(st.permutations(lines))
    return "\n".join(dt_lines + ([head] if head else []) + lines)


@SETTINGS
@given(text=st.one_of(curve_text(), st.text(max_size=400)))
def test_any_curve_text_gives_a_curve_or_one_line(text):
    out, exc = bounded(idf.parse_curve_csv, text, "c.csv")
    if exc is not None:
        one_line(exc, idf.NoiseInputError)
        return
    quantity, c = out
    assert quantity in ("avar", "adev", "wvar")
    assert 3 <= c.m.size <= idf.MAX_CURVE_POINTS
    assert np.all(c.m >= 1) and np.all(np.diff(c.m) > 0) and np.all(c.m == np.round(c.m))
    lo, hi = idf.CURVE_RANGE
    for a in (c.wv, c.lower, c.upper):
        assert np.all(np.isfinite(a)) and np.all((a >= lo) & (a <= hi))
    assert np.all(c.lower < c.upper) and idf.DT_RANGE[0] <= c.dt <= idf.DT_RANGE[1]


def mutate_station(draw) -> dict:
    doc = {"station": dict(STATION["station"]), "inputs": {k: dict(v) for k, v in STATION["inputs"].items()}}
    for _ in range(draw(st.integers(1, 4))):
        name = draw(st.sampled_from(sorted(doc["inputs"]) + ["bogus"]))
        key = draw(st.sampled_from(["value", "unit", "uncertainty", "half_width", "distribution", "dof", "source",
                                    "uncertainty_unit", "extra"]))
        val = draw(st.one_of(number, st.text(max_size=8), st.sampled_from(["mGal", "deg", "rad", "ppm", "K", "m",
                                                                          "normal", "rectangular", "u-shaped"]),
                             st.none(), st.lists(number, max_size=2), st.booleans()))
        target = doc["inputs"].setdefault(name, {})
        if val is None:
            target.pop(key, None)
        else:
            target[key] = val
    if draw(st.booleans()):
        doc["station"]["name"] = draw(st.text(max_size=5))
    return doc


@SETTINGS
@given(data=st.data())
def test_any_station_gives_a_station_or_one_line(data, tmp_path):
    doc = mutate_station(data.draw)
    out, exc = bounded(station_from_dict, doc)
    if exc is not None:
        one_line(exc, StationError)
    else:
        for k, inp in out.inputs.items():
            assert math.isfinite(inp.value) and math.isfinite(inp.u) and inp.u >= 0 and inp.dof >= 1, k
    try:
        text = tomli_w.dumps({k: v for k, v in doc.items()})
    except (TypeError, ValueError):
        text = data.draw(st.text(max_size=300))
    text = text if data.draw(st.booleans()) else text[: data.draw(st.integers(0, len(text)))]
    p = tmp_path / "st.toml"
    p.write_text(text)
    out, exc = bounded(read_station, p)
    if exc is not None:
        one_line(exc, StationError)


mapping_value = st.one_of(number, st.integers(-3, 12), st.text(max_size=6), st.booleans(),
                          st.sampled_from(["rates", "sampled-rates", "increments", "whitespace", "deg/s", "x", "-y"]),
                          st.lists(st.one_of(st.integers(-2, 8), st.sampled_from(["x", "y", "z"]), number), max_size=4))
MAPPING = {"kind": "increments", "delimiter": ",", "header_rows": 1, "comment": "#", "axes": ["x", "y", "z"],
           "signs": [1, 1, 1], "columns": {"time": 0, "gx": 1, "gy": 2, "gz": 3, "ax": 4, "ay": 5, "az": 6},
           "units": {"gyro": "rad", "accel": "m/s", "time": "s"},
           "site": {"latitude_deg": 30.5, "longitude_deg": 114.0, "height_m": 20.0}}


@st.composite
def mapping_doc(draw):
    """A valid mapping with one to four keys of it (or of its tables) changed, added or dropped."""
    doc = {k: (dict(v) if isinstance(v, dict) else v) for k, v in MAPPING.items()}
    for _ in range(draw(st.integers(0, 4))):
        table = doc.get(draw(st.sampled_from(["columns", "units", "site"])))
        where = table if isinstance(table, dict) and draw(st.booleans()) else doc
        key = draw(st.sampled_from(sorted(where) + ["max_gap_s", "other", "outer", "inner", "temperature", "latitude_deg"]))
        if draw(st.integers(0, 3)) == 0:
            where.pop(key, None)
        else:
            where[key] = draw(mapping_value)
    return doc


@SETTINGS
@given(doc=mapping_doc(), fmt=st.sampled_from(["csv", "csv", "txt", "psins"]), raw=st.text(max_size=300),
       use_raw=st.booleans())
def test_any_mapping_gives_a_mapping_or_one_line(doc, fmt, raw, use_raw, tmp_path):
    out, exc = bounded(parse_mapping, doc, fmt)
    if exc is not None:
        one_line(exc, ImportFileError)
    try:
        text = raw if use_raw else tomli_w.dumps(doc)
    except (TypeError, ValueError):
        text = raw
    p = tmp_path / "m.toml"
    p.write_text(text)
    out, exc = bounded(load_mapping, p, fmt)
    if exc is not None:
        one_line(exc, ImportFileError)
