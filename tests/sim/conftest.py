"""tests/sim: the reference simulator (the code before the compiled single pass) is a plain module next to
the tests; this folder goes on sys.path whatever pytest's import mode (the default "prepend" does it too)."""

import sys
from pathlib import Path

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)
