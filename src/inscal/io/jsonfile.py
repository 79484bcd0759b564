"""JSON conversion of results (NumPy arrays and scalars -> plain Python; NaN/inf -> null)."""

from __future__ import annotations

import math

import numpy as np


def to_jsonable(o):
    """A structure of dicts/lists/NumPy values as plain JSON-serialisable Python objects.
    Non-finite floats become ``None`` (JSON has no NaN)."""
    if isinstance(o, dict):
        return {str(k): to_jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [to_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return to_jsonable(o.tolist())
    if isinstance(o, (float, np.floating)):
        f = float(o)
        return f if math.isfinite(f) else None
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o
