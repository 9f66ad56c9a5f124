"""Parameter records: a params dataclass as a one-element numpy structured array.

Compiled code reads parameters by field name from a record (numba supports structured dtypes and
nested records), so a parameter vector has named, typed fields instead of positional indices.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def to_record(dtype: np.dtype[Any], source: object, **values: Any) -> np.ndarray:
    """One-element array of ``dtype``; each field from ``values`` or else ``source.<field>``."""
    rec = np.zeros(1, dtype=dtype)
    for name in dtype.names or ():
        rec[name] = values[name] if name in values else getattr(source, name)
    return rec
