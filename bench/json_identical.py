"""Every computing command's ``--json`` on the demo records, with the code before a change and with
the code now: byte-identical apart from timings and the output folder.

``python bench/json_identical.py --base REV [--quick]`` unpacks ``REV``'s ``src/`` (``git archive``, into
the system's temporary folder, kept so its numba cache survives between runs), then, once with those
sources and once with this tree's, runs ``inscal demo --json`` (simulation, Allan, every calibration
method, navigation) into a folder of its own and each command below on that folder's records (with every
record format exported and imported back, and the refusals of a wrong format).  Each
JSON output (or a failing command's last line) is canonicalised (the folders' paths replaced by ``<OUT>``
and ``<WORK>``, every ``elapsed_s``/``wall_s`` timing set to 0, the ``sha256:`` prefixes of record files
masked: an HDF5 record holds its creation time, so two writes of the same data hash differently; ISO
times masked: when a result was recorded, a record written) and the two are compared byte for byte; the
differing lines are printed.  Beside the computing commands, the uncertainty budget at a station (with
its JCGM 101 Monte Carlo, and before the run) and the runs into a fresh calibration database (a batch, two
calibrations with ``--station --serial``, the second reading the unit's history, and the stored budget).
Exit status 0 when every output is identical, 1 otherwise.
"""

from __future__ import annotations

import argparse
import difflib
import json
import re
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TIMING_KEYS = {"elapsed_s", "wall_s", "seconds", "runtime_s", "time_s", "seconds_per_record"}

# (name, arguments after ``inscal``); ``{D}`` is the tree's demo folder, ``{W}`` a scratch folder
COMMANDS = [
    ("calibrate-n25", ["calibrate", "{D}/n25.h5", "--method", "n25", "--out", "{W}/n25.toml", "--json"]),
    ("calibrate-six", ["calibrate", "{D}/n25.h5", "--method", "six-position", "--out", "{W}/six.toml", "--json"]),
    ("navigate", ["navigate", "{D}/n25-rotmod.h5", "--params", "{D}/params-n25.toml", "--json"]),
    ("allan", ["allan", "{D}/n25.h5", "--json"]),
    ("noise", ["noise", "{D}/n25.h5", "--stop", "100", "--channels", "gx,az", "--model", "WN", "--json"]),
    ("compensate", ["compensate", "{D}/n25.h5", "--params", "{D}/params-n25.toml", "--out", "{W}/comp.h5",
                    "--json"]),
    # the uncertainty budget: at a station, with its JCGM 101 Monte Carlo, before the run; the runs into the
    # database (a batch, a calibration with --serial and a budget that reads the unit's history) and what it stores
    ("budget", ["calibrate", "{D}/n25.h5", "--method", "n25", "--out", "{W}/budget.toml", "--station", "{S}",
                "--json"]),
    ("budget-mc", ["calibrate", "{D}/n25.h5", "--method", "six-position", "--out", "{W}/budget-mc.toml",
                   "--station", "{S}", "--mc", "100", "--mc-seed", "3", "--json"]),
    ("budget-before", ["observability", "s16", "--crlb", "--station", "{S}", "--json"]),
    ("db-add", ["db", "add", "U1", "--model", "FOG", "--db", "{W}/lab.sqlite", "--json"]),
    ("batch", ["batch", "{D}/n25.h5", "{D}/s16.h5", "--method", "six-position", "--serial", "U1", "--db",
               "{W}/lab.sqlite", "--scheduler", "none", "--no-progress", "--json"]),
    ("station-serial", ["calibrate", "{D}/n25.h5", "--method", "n25", "--out", "{W}/serial.toml", "--station", "{S}",
                        "--serial", "U1", "--db", "{W}/lab.sqlite", "--json"]),
    ("station-serial-2", ["calibrate", "{D}/n25.h5", "--method", "six-position", "--out", "{W}/serial-2.toml",
                          "--station", "{S}", "--serial", "U1", "--db", "{W}/lab.sqlite", "--supersedes", "1",
                          "--temperature-c", "21.5", "--json"]),
    ("db-budget", ["db", "budget", "U1", "--db", "{W}/lab.sqlite", "--json"]),
    # every record format out and back in, a calibration out, and the refusals of a format
    *[(f"export-{f}", ["export", "{D}/n25.h5", "--format", f, "--out", f"{{W}}/x.{s}", "--json"] + extra)
      for f, s, extra in (("csv", "csv", []), ("psins", "bin", ["--gimbal-out", "{W}/g.csv", "--path-out", "{W}/p.toml"]),
                          ("mat", "mat", []), ("kf-gins", "txt", []))],
    *[(f"import-{f}", ["import", f"{{W}}/x.{s}", "--format", f, "--out", f"{{W}}/in-{f}.h5", "--lat", "30.5", "--lon",
                       "120.5", "--height", "10", "--json"] + extra)
      for f, s, extra in (("csv", "csv", []), ("psins", "bin", ["--gimbal", "{W}/g.csv"]), ("mat", "mat", []),
                          ("kf-gins", "txt", []))],
    ("export-kalibr", ["export", "{D}/params-n25.toml", "--format", "kalibr", "--out", "{W}/k.yaml", "--json"]),
    ("import-unknown", ["import", "{W}/x.csv", "--format", "xls", "--out", "{W}/u.h5", "--json"]),
    ("import-dtype", ["import", "{W}/x.csv", "--format", "mat", "--dtype", "float32", "--out", "{W}/u.h5", "--json"]),
    ("import-no-site", ["import", "{W}/x.csv", "--format", "csv", "--lat", "30", "--out", "{W}/u.h5", "--json"]),
    # the database commands on a database of their own, and two refusals
    ("simulate", ["simulate", "psins19", "--out", "{W}/p19.h5", "--rate-hz", "20", "--seed", "1", "--json"]),
    ("db-init", ["db", "init", "--db", "{W}/lab2.sqlite", "--json"]),
    ("db-add-2", ["db", "add", "FOG-1", "--model", "FOG", "--db", "{W}/lab2.sqlite", "--json"]),
    ("calibrate-db", ["calibrate", "{D}/n25.h5", "--method", "n25", "--out", "{W}/db.toml", "--serial", "FOG-1",
                      "--db", "{W}/lab2.sqlite", "--operator", "Ada", "--json"]),
    ("db-list", ["db", "list", "--db", "{W}/lab2.sqlite", "--json"]),
    ("db-show", ["db", "show", "FOG-1", "--db", "{W}/lab2.sqlite", "--json"]),
    ("db-history", ["db", "history", "FOG-1", "--db", "{W}/lab2.sqlite", "--json"]),
    ("db-export", ["db", "export", "FOG-1", "--out", "{W}/again.toml", "--db", "{W}/lab2.sqlite", "--json"]),
    ("db-refused", ["db", "list", "--db", "{W}/lab2.sqlite", "--k", "0"]),
    ("calibrate-refused", ["calibrate", "{D}/n25.h5", "--method", "n25", "--out", "{W}/x.toml", "--mc-seed", "-1"]),
]
#: the station file of the budget's commands (the tests' typical station)
STATION = ROOT / "tests" / "data" / "station.toml"
#: an ISO time of the run (when a result was recorded, a record written): masked, as the timings are
ISO_TIME = re.compile(r"\d{4}-\d\d-\d\d[T ]\d\d:\d\d:\d\d(?:\.\d+)?(?:[+-]\d\d:\d\d|Z)?")


def base_tree(rev: str) -> Path:
    """``rev``'s ``src/`` unpacked once into the temporary folder."""
    sha = subprocess.run(["git", "rev-parse", rev], cwd=ROOT, check=True, capture_output=True,
                         text=True).stdout.strip()
    dest = Path(tempfile.gettempdir()) / f"inscal-json-{sha[:12]}"
    if not (dest / "src" / "inscal").is_dir():
        dest.mkdir(parents=True, exist_ok=True)
        blob = subprocess.run(["git", "archive", sha, "src"], cwd=ROOT, check=True, capture_output=True).stdout
        tar = dest / "src.tar"
        tar.write_bytes(blob)
        with tarfile.open(tar) as t:
            t.extractall(dest, filter="data")
        tar.unlink()
    return dest


def canonical(text: str, folders: list[Path]) -> str:
    """The JSON with the folders' paths as placeholders and the timings zeroed, re-dumped sorted."""
    for f, tag in zip(folders, ("<OUT>", "<WORK>")):
        text = text.replace(str(f), tag)
    text = re.sub(r"sha256:[0-9a-f]+", "sha256:<HASH>", text)
    text = ISO_TIME.sub("<TIME>", text)
    if not text.startswith(("{", "[")):
        return text

    def zero(o):
        if isinstance(o, dict):
            return {k: (0 if k in TIMING_KEYS else zero(v)) for k, v in o.items()}
        if isinstance(o, list):
            return [zero(v) for v in o]
        return o

    return json.dumps(zero(json.loads(text)), indent=1, sort_keys=True)


def run_tree(src: Path, out: Path, quick: bool, only: set[str] | None = None, records: Path | None = None) -> dict[str, str]:
    """Every command's canonical JSON with the sources ``src``, writing under ``out``; ``records``: a folder of
    records both trees read instead of each running the demo."""
    env = dict(os.environ, PYTHONPATH=str(src))
    inscal = [sys.executable, "-c", "import sys; from inscal.cli import main; sys.argv[0] = 'inscal'; sys.exit(main())"]
    demo, work = (out / "demo", out / "work") if records is None else (records, out / "work")
    work.mkdir(parents=True, exist_ok=True)
    runs = [] if records is not None else [
        ("demo", ["demo", "--out", str(demo), "--force", "--json"] + (["--quick"] if quick else []))]
    runs += [(n, [a.replace("{D}", str(demo)).replace("{W}", str(work)).replace("{S}", str(STATION)) for a in args])
             for n, args in COMMANDS if only is None or n in only]
    res = {}
    for name, args in runs:
        p = subprocess.run(inscal + args, env=env, capture_output=True, text=True)
        if p.returncode != 0:  # its last line, and its JSON when it printed one (a batch with a failed record)
            res[name] = canonical(f"exit {p.returncode}: {p.stderr.strip().splitlines()[-1:]}", [demo, work])
            if p.stdout.lstrip().startswith(("{", "[")):
                res[name] += "\n" + canonical(p.stdout, [demo, work])
        else:
            res[name] = canonical(p.stdout, [demo, work])
        print(f"  {src}: {name} done", flush=True)
    return res


NUMBER = re.compile(r"-?\d+\.?\d*(?:[eE][+-]?\d+)?")


def numeric_summary(a: str, b: str) -> str:
    """How two outputs differ: the count of differing lines and, where they differ only in numbers, the
    largest relative difference of a number (what a last-bit change of the arithmetic leaves)."""
    la, lb = a.splitlines(), b.splitlines()
    pairs = [(x, y, i) for i, (x, y) in enumerate(zip(la, lb)) if x != y]
    if len(la) != len(lb) or any(NUMBER.sub("#", x) != NUMBER.sub("#", y) for x, y, _ in pairs):
        return f"{len(pairs)} lines differ, not only in numbers"
    rel, where = 0.0, ""
    for x, y, i in pairs:
        for u, v in zip(NUMBER.findall(x), NUMBER.findall(y)):
            fu, fv = float(u), float(v)
            if fu != fv and abs(fu - fv) / max(abs(fu), abs(fv)) > rel:
                keys = [ln.strip() for ln in la[max(0, i - 40):i + 1] if '":' in ln][-3:]
                rel, where = abs(fu - fv) / max(abs(fu), abs(fv)), f"{' '.join(keys)} -> {y.strip()}"
    return f"{len(pairs)} lines differ, only in numbers: largest relative difference {rel:.2g} ({where})"


def main() -> int:
    """Run both trees and compare; print one line per command."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare against (e.g. the branch point)")
    ap.add_argument("--quick", action="store_true", help="the demo's shorter navigation run")
    ap.add_argument("--only", default=None, help="comma-separated names of the commands to run (the demo always)")
    ap.add_argument("--records", type=Path, default=None,
                    help="a folder with n25.h5 and s16.h5 that both trees read instead of running the demo each "
                         "(the demo's own output is then not compared; its commands need the demo's parameter files)")
    a = ap.parse_args()
    base = base_tree(a.base)
    with tempfile.TemporaryDirectory(prefix="inscal-json-") as tmp:
        only = None if a.only is None else set(a.only.split(","))
        rec = None if a.records is None else a.records.resolve()
        old = run_tree(base / "src", Path(tmp) / "base", a.quick, only, rec)
        new = run_tree(ROOT / "src", Path(tmp) / "now", a.quick, only, rec)
    bad = 0
    for name in old:
        same = old[name] == new[name]
        bad += not same
        print(f"{name:16s} {'identical' if same else 'DIFFERENT'} ({len(new[name])} bytes)")
        if not same:
            diff = difflib.unified_diff(old[name].splitlines(), new[name].splitlines(), "base", "now", n=0,
                                        lineterm="")
            lines = list(diff)
            print("\n".join(lines[:12]))
            print(f"  {numeric_summary(old[name], new[name])}")
    print(f"{len(old) - bad} of {len(old)} outputs identical")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
