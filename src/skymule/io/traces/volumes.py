"""AADM data-volume files: one number (Mbit) a line, LW1..LW4."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from skymule.io.traces.table import NUMBER_RE, file_errors
from skymule.io.traces.trace import TraceError, quote
from skymule.limits import BUFFER_LIMIT, MAX_BUFFER_MBIT


def read_volumes(path: str | os.PathLike[str]) -> np.ndarray:
    """(N,) data volumes in Mbit from an AADM volume file: one number a line.

    Blank lines and lines starting with ``#`` are ignored. Values must be finite,
    non-negative and at most :data:`skymule.limits.MAX_BUFFER_MBIT`.

    Raises:
        TraceError: missing/unreadable file, a bad line (named by its line number), or
            no values at all.
    """
    label = os.fspath(path)
    with file_errors(label, "a volume file"):
        text = Path(path).read_text(encoding="utf-8-sig")
    values: list[float] = []
    for number, line in enumerate(text.splitlines(), start=1):
        cell = line.strip()
        if not cell or cell.startswith("#"):
            continue
        if re.fullmatch(NUMBER_RE, cell) is None:
            raise TraceError(
                f"{label}: line {number}: {quote(cell)} is not a number "
                f"(expected one data volume in Mbit per line)"
            )
        value = float(cell)
        if not math.isfinite(value) or value < 0:
            raise TraceError(
                f"{label}: line {number}: {quote(cell)} is not a valid volume "
                f"(expected a finite, non-negative number of Mbit)"
            )
        if value > MAX_BUFFER_MBIT:
            raise TraceError(f"{label}: line {number}: {quote(cell)} Mbit: {BUFFER_LIMIT}")
        values.append(value)
    if not values:
        raise TraceError(f"{label}: no volumes (expected one number in Mbit per line)")
    return np.array(values, dtype=float)
