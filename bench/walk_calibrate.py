"""The walk of ``inscal calibrate REC --method M --station FILE.toml --serial X``: the command's calls into the
library, and every climb from a lower layer back up into ``inscal.cli``.

``python bench/walk_calibrate.py [--method n25] [--mc N]`` simulates a short record, registers a unit in a
fresh database, then runs the command in this process with a profile hook (:func:`sys.setprofile`) on every
Python call.  A call whose nearest ``inscal`` caller lies in another top-level package than the callee is a
step between layers; printed are the steps out of ``cli`` (the command's calls into the library, consecutive
calls of one function folded, imports left out), their count, and every climb: a call from a lower layer into
``cli`` (a callback: the lower layer runs code of the command), with who called it and whether it is the end of
the command (its output unit, :func:`inscal.io.files.output_unit`, runs the command's database commit before the
renames and its clean-up after them, by design).  The sources are the ones on ``PYTHONPATH``: run it once per
tree to compare.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import sys
import tomllib
import tempfile
from contextlib import redirect_stdout
from pathlib import Path

from inscal.io import read_record

ROOT = Path(__file__).resolve().parent.parent
STATION = ROOT / "tests" / "data" / "station.toml"
#: the steps of the command's output unit (its database commit and clean-up, run by design as it publishes)
END = {"inscal.io.files.output_unit", "inscal.io.files.after_unit"}


def package(frame) -> str | None:
    """The top-level inscal package of ``frame``'s code (``cli``, ``lab``...), None outside inscal."""
    name = frame.f_globals.get("__name__", "")
    if not name.startswith("inscal."):
        return None
    return name.split(".")[1]


def trace(fn):
    """Run ``fn()`` with the profile hook; ``(steps, climbs)``: every cross-package call, and those into cli."""
    steps, climbs = [], []

    def hook(frame, event, arg):
        if event != "call":
            return
        callee = package(frame)
        if callee is None:
            return
        code = frame.f_code
        caller, f = None, frame.f_back
        while f is not None:
            caller = package(f)
            if caller is not None:
                break
            f = f.f_back
        if caller is None or caller == callee:
            return
        where = f"{frame.f_globals['__name__']}.{code.co_qualname}"
        steps.append((caller, callee, where))
        if callee == "cli":
            who = f"{f.f_globals['__name__']}.{f.f_code.co_qualname}"
            climbs.append((where, who, who in END))

    sys.setprofile(hook)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return steps, climbs


def site_station(rec: Path, out: Path) -> Path:
    """The tests' station file moved to the site of record ``rec`` (its latitude, height and gravity), at ``out``."""
    site = read_record(rec).site
    doc = tomllib.loads(STATION.read_text(encoding="utf-8"))
    doc["inputs"]["latitude"]["value"] = math.degrees(site.latitude)
    doc["inputs"]["height"]["value"] = float(site.height)
    doc["inputs"]["gravity"]["value"] = float(site.gravity)
    lines = [f'[station]\nname = "{doc["station"]["name"]}"\n']
    for name, table in doc["inputs"].items():
        lines.append(f"[inputs.{name}]")
        lines += [f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"' for k, v in table.items()]
        lines.append("")
    out.write_text("\n".join(lines), encoding="utf-8")
    return out


def main() -> int:
    """Prepare the record and the database, trace the command, print the walk."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="n25")
    ap.add_argument("--mc", type=int, default=None, help="also the budget's JCGM 101 Monte Carlo (N trials)")
    a = ap.parse_args()
    from typer.testing import CliRunner

    from inscal.cli.app import app

    runner = CliRunner()
    with tempfile.TemporaryDirectory(prefix="inscal-walk-") as tmp:
        t = Path(tmp)
        db, rec = t / "lab.sqlite", t / "r.h5"
        scen = "s16" if a.method.startswith("systematic") else "n25"
        for args in (["db", "add", "U1", "--model", "FOG", "--db", db],
                     ["simulate", scen, "--out", rec, "--seed", 2, "--rate-hz", 20]):
            r = runner.invoke(app, [str(x) for x in args])
            assert r.exit_code == 0, r.output
        station = site_station(rec, t / "station.toml")
        argv = ["calibrate", rec, "--method", a.method, "--out", t / "p.toml", "--station", station, "--serial", "U1",
                "--db", db, "--json"] + ([] if a.mc is None else ["--mc", a.mc])
        box = {}

        def run():
            box["r"] = runner.invoke(app, [str(x) for x in argv])

        with redirect_stdout(io.StringIO()):
            steps, climbs = trace(run)
        r = box["r"]
        assert r.exit_code == 0, r.output
        assert "budget" in json.loads(r.stdout)
    print(f"inscal calibrate ... --method {a.method} --station station.toml --serial U1"
          + ("" if a.mc is None else f" --mc {a.mc}"))
    print("walk at the command's level (its calls into the library, consecutive repeats folded; imports left out):")
    folded = []
    for s in steps:
        if "cli" not in s[:2] or s[2].endswith("<module>"):
            continue
        if folded and folded[-1][0] == s:
            folded[-1][1] += 1
        else:
            folded.append([s, 1])
    for (caller, callee, where), n in folded:
        print(f"  {caller:12s} -> {callee:12s} {where}" + (f"  (x{n})" if n > 1 else ""))
    descents = sum(n for (caller, _, _), n in folded if caller == "cli")
    before = [c for c in climbs if not c[2]]
    print(f"calls from cli into the library: {descents} (each returns to cli); calls from a lower layer into cli: "
          f"{len(climbs)} "
          f"({len(before)} before the output unit's publication, {len(climbs) - len(before)} in it)")
    for where, who, end in climbs:
        print(f"  climb: {who} -> {where}" + ("  [publication]" if end else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
