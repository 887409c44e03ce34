"""Random fixed-trajectory missions and policy specs for the engine tests, and log equality.

Tracks with quantised SNR (rate ties), NaN and low SNR (rate 0), buffers that empty early or
never, slot lengths that do not divide the download window, sometimes per-slot fading on a
Shannon table, geometry partly or all absent.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from skymule.flight.paths import Track
from skymule.metrics.flights import MissionLog
from skymule.radio.rates import Shannon
from skymule.scenario import PolicySpec

LOG_FIELDS = (
    "policy", "sensor_names", "slot_s", "buffers_bit", "position_m", "end_position_m", "snr_db",
    "rate_bps", "served", "downloaded_bit", "remaining_bit", "hovering", "home_m",
    "hover_points_m", "visit_radius_m", "target", "aadm_window_s", "affected", "chosen",
    "battery_used_j",
)  # fmt: skip


def random_mission(base: Any, rng: np.random.Generator, n_sensors: int) -> Any:
    """A mission with a random track, buffers, slot length and download window."""
    n_samples = int(rng.integers(1, 40))
    snr = rng.choice([-20.0, -5.0, 3.0, 9.0, 12.0, 25.0], size=(n_samples, n_sensors))
    snr += rng.choice([0.0, 0.0, 0.1], size=snr.shape)  # SNR ties and near-ties
    snr[rng.random(snr.shape) < 0.1] = np.nan
    position = np.cumsum(rng.normal(0, 10, (n_samples, 3)), axis=0)
    track = Track(position_m=position, snr_db=snr, hold_at_end=bool(rng.integers(2)))
    buffers = rng.choice([0.0, 1e5, 1e6, 3e6, 2e7], size=n_sensors) * rng.random(n_sensors)
    buffers[rng.random(n_sensors) < 0.3] = rng.choice([0.0, 1.4e6 * 2.41, 2.1e6])
    names = tuple(f"S{i}" for i in range(n_sensors))
    n_slots = int(rng.integers(1, 60))
    slot_s = float(rng.choice([1.0, 0.5, 2.0]))
    # the AADM download window closing mid-mission (and mid-slot) in some missions
    window_s = float(rng.uniform(0, n_slots + 1)) * slot_s if rng.random() < 0.3 else None
    return replace(
        base,
        sensor_names=names,
        sensor_m=np.zeros((n_sensors, 3)),
        buffers_bit=buffers,
        n_slots=n_slots,
        slot_s=slot_s,
        track=track,
        aadm_window_s=window_s,
        hover_points_m=None,
    )


def random_spec(rng: np.random.Generator) -> PolicySpec:
    return PolicySpec(
        name=str(rng.choice(["greedy", "hgad"])),
        hover_threshold=float(rng.choice([1.0, 0.5, 0.8, rng.uniform(0.05, 1.0)])),
        max_hover_s=float(rng.choice([60.0, 1.0, 2.5, 5.0])),
    )


def random_geometry(rng: np.random.Generator, n_sensors: int) -> dict[str, object]:
    """Mission geometry near random tracks; sometimes partly or all absent."""
    if rng.random() < 0.15:
        return {"home_m": None, "hover_points_m": None, "visit_radius_m": 50.0}
    hover = rng.normal(0, 30, (n_sensors, 2))
    hover[rng.random(n_sensors) < 0.2] = np.nan
    return {
        "home_m": None if rng.random() < 0.2 else rng.normal(0, 20, 2),
        "hover_points_m": None if rng.random() < 0.1 else hover,
        "visit_radius_m": float(rng.choice([5.0, 20.0, 50.0])),
    }


def with_geometry(missions: list[Any], geometry: list[dict[str, object]]) -> list[Any]:
    return [replace(m, **geo) for m, geo in zip(missions, geometry, strict=True)]


def with_random_fading(mission: Any, rng: np.random.Generator) -> Any:
    """Half the time: per-slot fading (T, N) [dB]; a third of those on a Shannon rate table."""
    if rng.random() < 0.5:
        return mission
    fading = rng.normal(0, 6, (mission.n_slots, mission.n_sensors))
    mission = replace(mission, fading_db=fading)
    return replace(mission, rate_table=Shannon()) if rng.random() < 0.3 else mission


def assert_logs_equal(got: MissionLog, want: MissionLog) -> None:
    """Every field of two flights' logs: the same values, dtypes and shapes (NaN = NaN)."""
    assert got.n_slots == want.n_slots
    for name in LOG_FIELDS:
        ours, theirs = getattr(got, name), getattr(want, name)
        if isinstance(theirs, np.ndarray):
            assert isinstance(ours, np.ndarray), name
            np.testing.assert_array_equal(ours, theirs, err_msg=name, strict=True)
        else:
            assert ours == theirs, name


#: How close a compiled twin's sums come to numpy's (numba sums in order, numpy pairwise).
TWIN_RTOL = 1e-12


def assert_summaries_equal(got: Any, want: Any, rtol: float = 0.0, key: str = "") -> None:
    """Field for field: same keys in the same order, same types, same values (NaN = NaN);
    floats within ``rtol`` (0: exactly; :data:`TWIN_RTOL` between a compiled twin and numpy),
    into nested dicts and lists."""
    assert type(got) is type(want), key
    if isinstance(want, dict):
        assert list(got) == list(want), key
        for name, value in want.items():
            assert_summaries_equal(got[name], value, rtol, f"{key}.{name}")
    elif isinstance(want, list):
        assert len(got) == len(want), key
        for index, (ours, theirs) in enumerate(zip(got, want, strict=True)):
            assert_summaries_equal(ours, theirs, rtol, f"{key}[{index}]")
    elif isinstance(want, float) and np.isnan(want):
        assert np.isnan(got), key
    elif isinstance(want, float):
        assert abs(got - want) <= rtol * abs(want), (key, got, want)
    else:
        assert got == want, (key, got, want)
