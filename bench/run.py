"""Run every bench/bench_*.py script in turn (``make bench``) and print their figures."""

import subprocess
import sys
from pathlib import Path

here = Path(__file__).parent
rc = 0
for script in sorted(here.glob("bench_*.py")):
    print(f"== {script.name}", flush=True)
    r = subprocess.run([sys.executable, str(script)], cwd=here.parent)
    rc |= r.returncode
sys.exit(rc)
