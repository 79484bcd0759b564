"""Two or three examples of every command, shown under its options in ``--help`` and in the CLI reference.

They follow one session: ``n25.h5`` is ``inscal simulate n25``'s record, ``n25.toml`` its calibration,
``lab.sqlite`` the laboratory's database with the unit ``FOG-0042``.  The tests parse every example with
its command's options (tests/cli/test_help.py) and run a few of them.
"""

from __future__ import annotations

#: command (``"db add"`` for a subcommand) -> its examples, each a whole command line
EXAMPLES: dict[str, tuple[str, ...]] = {
    "simulate": (
        "inscal simulate n25 --out n25.h5 --seed 1",
        "inscal simulate s16 --out s16.h5 --seed 1 --rate-hz 100",
        "inscal simulate n25-rotmod --out rm.h5 --duration-h 2 --no-noise",
    ),
    "calibrate": (
        "inscal calibrate n25.h5 --method n25 --out n25.toml",
        "inscal calibrate s16.h5 --method systematic51 --out s16-51.toml --plots plots/",
        "inscal calibrate n25.h5 --method n25 --out n25.toml --serial FOG-0042 --db lab.sqlite --station station.toml",
    ),
    "compensate": (
        "inscal compensate n25.h5 --params n25.toml --out n25-comp.h5",
        "inscal compensate run.h5 --params thermal.toml --out run-comp.h5 --temperature 25",
    ),
    "navigate": (
        "inscal navigate rm.h5 --params n25.toml --plot nav.png",
        "inscal navigate rm.h5 --mode damped --vertical damped --json",
    ),
    "montecarlo": (
        "inscal montecarlo --list",
        "inscal montecarlo n25-fig5 --runs 200 --out mc-fig5 --seed 1",
        "inscal montecarlo s16-table2 --runs 50 --out mc-s16 --scheduler none",
    ),
    "allan": (
        "inscal allan st.h5",
        "inscal allan st.h5 --start 60 --stop 1800 --plot allan.png",
    ),
    "demo": (
        "inscal demo",
        "inscal demo --out demo-output --quick --json",
    ),
    "report": (
        "inscal report n25.h5 --params n25.toml --out n25-report.html",
        "inscal report st.h5 --noise noise.toml --out noise-report.html",
    ),
    "observability": (
        "inscal observability s16 --states 51",
        "inscal observability s16 --states 51 --crlb",
        "inscal observability n25-twelve --crlb --station station.toml --method n25",
    ),
    "import": (
        "inscal import n25.csv --format csv --out n25-imported.h5 --lat 30.686651 --lon 120.664265 --height 0",
        "inscal import run.bin --format psins --out run.h5 --rate-hz 100 --lat 34.2 --lon 108.9 --height 380",
    ),
    "export": (
        "inscal export n25.h5 --format csv --out n25.csv",
        "inscal export n25.toml --format kalibr --out imu.yaml",
        "inscal export noise.toml --format kf-gins --out imunoise.txt",
    ),
    "design": (
        "inscal design --minutes 20 --out path20.toml",
        "inscal design --minutes 20 --candidates 32 --scheduler none --out path20.toml",
    ),
    "batch": (
        "inscal batch runs/ --method n25 --db lab.sqlite",
        "inscal batch n25.h5 --method n25 --serial FOG-0042 --db lab.sqlite --scheduler none",
        "inscal batch --manifest runs.csv --method n25 --register --model FOG-IMU --db lab.sqlite",
    ),
    "noise": (
        "inscal noise st.h5",
        "inscal noise st.h5 --channels gx,az --model WN --out noise.toml --plot noise.png",
        "inscal noise --from-curve adev.csv --kind gyro",
    ),
    "db init": (
        "inscal db init --db lab.sqlite",
        "inscal db init --db postgresql://lab@dbhost/calib",
    ),
    "db upgrade": (
        "inscal db upgrade --db lab.sqlite",
        "inscal db upgrade --db postgresql://lab@dbhost/calib --json",
    ),
    "db recover": (
        "inscal db recover --db lab.sqlite",
        "inscal db recover --db lab.sqlite --wait 30 --json",
    ),
    "db add": (
        "inscal db add FOG-0042 --model FOG-IMU --db lab.sqlite",
        "inscal db add FOG-0042 n25.toml --data n25.h5 --operator Ada --db lab.sqlite",
    ),
    "db list": (
        "inscal db list --db lab.sqlite",
        "inscal db list --db lab.sqlite --flagged --k 2",
    ),
    "db show": (
        "inscal db show FOG-0042 --db lab.sqlite",
        "inscal db show FOG-0042 --result 3 --covariance --db lab.sqlite",
    ),
    "db budget": (
        "inscal db budget FOG-0042 --db lab.sqlite",
        "inscal db budget FOG-0042 --result 3 --json --db lab.sqlite",
    ),
    "db export": (
        "inscal db export FOG-0042 --out current.toml --db lab.sqlite",
        "inscal db export FOG-0042 --result 3 --out result3.toml --db lab.sqlite",
    ),
    "db history": (
        "inscal db history FOG-0042 --db lab.sqlite",
        "inscal db history FOG-0042 --method n25 --plot drift.png --db lab.sqlite",
    ),
    "db certificate": (
        "inscal db certificate FOG-0042 --out certificates/ --db lab.sqlite",
        "inscal db certificate FOG-0042 --out cert.html --no-pdf --lab \"Inertial Lab, Xi'an\" --db lab.sqlite",
    ),
}


def epilog(command: str) -> str | None:
    """The ``Examples`` block of ``command``'s help (None when it has none)."""
    lines = EXAMPLES.get(command)
    if not lines:
        return None
    return "Examples:\n\n" + "\n".join(f"  {line}" for line in lines)
