"""Rate tables: SNR [dB] -> spectral efficiency [bit/s/Hz] -> rate [bit/s].

A rate table is a frozen dataclass with ``efficiency(snr_db)``; rate = efficiency x bandwidth.
Tables resolve by name through :func:`resolve_rate_table` (a built-in name or a CSV path).
Missing SNR samples (NaN) have no link: efficiency 0.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from skymule.errors import SkymuleError
from skymule.limits import MAX_EFFICIENCY_BPS_HZ
from skymule.registry import Registry
from skymule.rules.contract import seen_snr_db

#: AERPAW AADM controller's LTE CQI table: (SNR threshold dB, efficiency b/s/Hz), the rate is
#: that of the highest threshold the SNR reaches; below -6.7 dB there is no link.
#: Source: AERPAW Autonomous Data Mule challenge controller (as given in the core issue).
AADM_LTE_CQI: tuple[tuple[float, float], ...] = (
    (-6.7, 0.15),
    (-4.7, 0.23),
    (-2.3, 0.38),
    (0.2, 0.60),
    (2.4, 0.88),
    (4.3, 1.18),
    (5.9, 1.48),
    (8.1, 1.91),
    (10.3, 2.41),
    (11.7, 2.73),
    (14.1, 3.32),
    (16.3, 3.90),
    (18.7, 4.52),
    (21.0, 5.12),
    (22.7, 5.55),
)


@dataclass(frozen=True)
class StepTable:
    """Threshold table: efficiency of the highest threshold reached (ascending thresholds)."""

    name: str
    thresholds_db: tuple[float, ...]
    efficiencies: tuple[float, ...]

    @cached_property
    def _lookup(self) -> tuple[np.ndarray, np.ndarray]:
        """(thresholds, efficiencies with 0 prepended) as arrays, built once per table (the
        engines look rates up every slot)."""
        thresholds = np.asarray(self.thresholds_db, float)
        return thresholds, np.concatenate([[0.0], np.asarray(self.efficiencies, float)])

    def efficiency(self, snr_db: np.ndarray) -> np.ndarray:
        thresholds, table = self._lookup
        # searchsorted(side="right") counts thresholds <= snr, i.e. ">= threshold" semantics;
        # no link (NaN -> -inf) reaches no threshold
        index = np.searchsorted(thresholds, seen_snr_db(snr_db), side="right")
        return table[index]


@dataclass(frozen=True)
class Shannon:
    """Shannon capacity: log2(1 + SNR) with an optional cap [bit/s/Hz]."""

    name: str = "shannon"
    max_efficiency: float = np.inf

    def efficiency(self, snr_db: np.ndarray) -> np.ndarray:
        snr = seen_snr_db(snr_db)  # no link: efficiency 0
        return np.minimum(np.log2(1.0 + 10.0 ** (snr / 10.0)), self.max_efficiency)


RateTable = StepTable | Shannon

BUILTIN_RATE_TABLES: Registry[RateTable] = Registry(
    "radio.rate_table", extra_allowed="or a path to an existing CSV (snr_db, efficiency)"
)
"""Rate tables by name (``[radio] rate_table``)."""

BUILTIN_RATE_TABLES.register(
    "aadm-lte-cqi",
    StepTable("aadm-lte-cqi", tuple(t for t, _ in AADM_LTE_CQI), tuple(e for _, e in AADM_LTE_CQI)),
)
BUILTIN_RATE_TABLES.register("shannon", Shannon())


def read_rate_csv(path: Path) -> StepTable:
    """CSV with header ``snr_db,efficiency``: a threshold table (sorted on load).

    Every value finite, each threshold once, and the efficiency from 0 to
    :data:`skymule.limits.MAX_EFFICIENCY_BPS_HZ` and never lower at a higher SNR (a better link
    is never slower: the engines and bounds rely on it); else one line naming the row.
    """
    try:
        lines = [ln.strip() for ln in path.read_text().splitlines() if ln.strip()]
    except OSError as exc:
        raise SkymuleError(f"radio.rate_table: cannot read {path} ({exc.strerror})") from None
    if not lines or [h.strip().lower() for h in lines[0].split(",")] != ["snr_db", "efficiency"]:
        raise SkymuleError(f"{path}: rate table CSV needs the header 'snr_db,efficiency'")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        try:
            snr, eff = (float(v) for v in line.split(","))
        except ValueError:
            raise SkymuleError(
                f"{path}: line {number}: {line!r} is not two numbers 'snr_db,efficiency'"
            ) from None
        if not math.isfinite(snr):
            raise SkymuleError(f"{path}: line {number}: snr_db {snr} must be a finite number")
        if not (math.isfinite(eff) and 0 <= eff <= MAX_EFFICIENCY_BPS_HZ):
            raise SkymuleError(
                f"{path}: line {number}: efficiency {eff} must be a finite number from 0 to "
                f"{MAX_EFFICIENCY_BPS_HZ:g} bit/s/Hz (1024-QAM carries 10)"
            )
        rows.append((snr, eff, number))
    if not rows:
        raise SkymuleError(f"{path}: rate table CSV has no rows")
    rows.sort()
    for (snr_a, eff_a, line_a), (snr_b, eff_b, line_b) in itertools.pairwise(rows):
        if snr_b == snr_a:
            raise SkymuleError(
                f"{path}: lines {line_a} and {line_b} both give snr_db {snr_a:g}; "
                "give each threshold once"
            )
        if eff_b < eff_a:
            raise SkymuleError(
                f"{path}: line {line_b}: efficiency {eff_b:g} at snr_db {snr_b:g} is lower than "
                f"{eff_a:g} at {snr_a:g} (line {line_a}); a higher SNR never gives a lower rate"
            )
    return StepTable(str(path), tuple(r[0] for r in rows), tuple(r[1] for r in rows))


def resolve_rate_table(spec: str, base_dir: Path | None = None) -> RateTable:
    """A built-in rate table by name, or a CSV file path (relative to ``base_dir``)."""
    if spec in BUILTIN_RATE_TABLES:
        return BUILTIN_RATE_TABLES[spec]
    path = Path(spec)
    if base_dir is not None and not path.is_absolute():
        path = base_dir / path
    if path.suffix.lower() == ".csv" and path.exists():
        return read_rate_csv(path)
    raise BUILTIN_RATE_TABLES.error(spec)


def rate_bps(table: RateTable, snr_db: np.ndarray, bandwidth_hz: float) -> np.ndarray:
    """Rate [bit/s] for SNR values [dB] (any shape)."""
    return table.efficiency(snr_db) * bandwidth_hz
