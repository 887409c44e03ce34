"""The benchmarks' tiny-size mode: ``SKYMULE_BENCH_TINY=1 python benchmarks/bench_X.py``.

With the variable set (to anything but ``0``) every benchmark runs at a size that takes seconds,
so that tests/test_benchmarks_smoke.py can run them all and none rots; the figures it prints
then are not measurements. Explicit sizes on the command line still win.
"""

from __future__ import annotations

import os
from typing import TypeVar

TINY_ENV = "SKYMULE_BENCH_TINY"

T = TypeVar("T")


def tiny() -> bool:
    """True when the tiny-size mode is asked for."""
    return os.environ.get(TINY_ENV, "").strip() not in ("", "0")


def size(full: T, small: T) -> T:
    """``small`` in tiny-size mode, ``full`` otherwise."""
    return small if tiny() else full
