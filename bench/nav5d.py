"""S16's 5-day static navigation comparison (S16 section 4.2): the 51-state against the 30-state
calibration (:func:`inscal.analysis.nav5d.compare_5day`), as a table.

    .venv/bin/python bench/nav5d.py [--seed 2016] [--days 5] [--json out.json]   (--help for all options)
"""

import argparse
import json

from inscal.analysis import nav5d
from inscal.analysis.nav5d import ORIENTATIONS
from inscal.io.jsonfile import to_jsonable


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python bench/nav5d.py", description=nav5d.__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=2016)
    ap.add_argument("--scenario", default="s16-table3")
    ap.add_argument("--orientations", default=",".join(ORIENTATIONS))
    ap.add_argument("--days", type=float, default=5.0)
    ap.add_argument("--nav-rate", type=float, default=10.0)
    ap.add_argument("--nav-noise", action="store_true", help="navigation record with the scenario's noise")
    ap.add_argument("--cal-noise-scale", type=float, default=1.0, help="factor on the calibration record's ARW and VRW")
    ap.add_argument("--no-consistent-30", action="store_true", help="skip the NIS-consistent 30-state calibration")
    ap.add_argument("--json", help="also write the figures to this JSON file")
    a = ap.parse_args(argv)
    res = nav5d.compare_5day(a.seed, scenario=a.scenario, orientations=tuple(a.orientations.split(",")), days=a.days,
                       nav_rate_hz=a.nav_rate, nav_noise=a.nav_noise, cal_noise_scale=a.cal_noise_scale,
                       consistent_30=not a.no_consistent_30)
    print(nav5d.format_table(res))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(to_jsonable(res), fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
