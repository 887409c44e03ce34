"""The fast prefix-LP path (column generation) equals the plain every-column reference."""

from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import preset_mission
from skymule.bounds.fixed import fixed_path_bound, mission_track_rates, record_samples
from skymule.bounds.prefix_lp import dual_bounds, prefix_lp, prefix_lp_columns
from skymule.bounds.result import BoundError

REL = 1e-6


def random_instance(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, int]:
    """Rates (K, N) with zeros (or ties), buffers (some empty or huge) and a slot count T."""
    k = int(rng.integers(1, 60))
    n = int(rng.integers(1, 7))
    if rng.random() < 0.3:  # small integers: ties and degenerate LPs
        rate = rng.integers(0, 4, size=(k, n)).astype(float)
    else:
        rate = rng.uniform(0.0, 10.0, size=(k, n)) ** 2 * (rng.random((k, n)) < 0.7)
    buf = rng.uniform(0.0, 400.0, size=n) * (rng.random(n) < 0.9)
    buf[rng.random(n) < 0.15] = 1e9
    n_slots = int(rng.integers(1, 2 * k + 5))
    return rate, buf, n_slots


def test_columns_equal_full_on_random_instances() -> None:
    rng = np.random.default_rng(20261130)
    several_rounds = 0
    for _ in range(40):
        rate, buf, n_slots = random_instance(rng)
        dt = float(rng.choice([0.5, 1.0, 2.0]))
        fast = fixed_path_bound(rate, buf, dt, n_slots, solver="columns")
        full = fixed_path_bound(rate, buf, dt, n_slots, solver="full")
        assert fast.upper_bound_bit == pytest.approx(full.upper_bound_bit, rel=REL, abs=1e-9)
        # the schedule it returns collects the bound and spends the whole mission
        assert np.sum(rate * fast.served_time_s) == pytest.approx(
            fast.upper_bound_bit, rel=REL, abs=1e-6
        )
        assert fast.dwell_time_s.sum() == pytest.approx(n_slots * dt)
        for hold in (True, False):  # the paper's no-hover LP
            kw = {"hover_allowed": False, "hold_at_end": hold}
            plain = fixed_path_bound(rate, buf, dt, n_slots, solver="columns", **kw)
            ref = fixed_path_bound(rate, buf, dt, n_slots, solver="full", **kw)
            assert plain.upper_bound_bit == pytest.approx(ref.upper_bound_bit, rel=REL, abs=1e-9)
            assert np.sum(rate * plain.served_time_s) == pytest.approx(
                plain.upper_bound_bit, rel=REL, abs=1e-6
            )
        counts = re.search(r"\((\d+) prefix LPs, (\d+) HiGHS solves\)", fast.status)
        assert counts is not None, fast.status
        several_rounds += int(counts[2]) > int(counts[1])
    assert several_rounds > 0  # the pricing loop (not only its first LP) is exercised


def test_each_prefix_lp_equals_the_reference_from_any_start() -> None:
    rng = np.random.default_rng(7)
    for _ in range(25):
        rate, buf, n_slots = random_instance(rng)
        reach = rate[: min(rate.shape[0], n_slots)]
        candidates = record_samples(reach)
        for last in rng.choice(candidates, size=min(3, candidates.size), replace=False):
            ref = prefix_lp(reach, buf, 1.0, n_slots, int(last), "highs-ipm")
            guess = rng.uniform(0.0, 1.2, size=rate.shape[1]) * (rng.random() < 0.7)
            fast = prefix_lp_columns(reach, buf, 1.0, n_slots, int(last), guess, "highs-ipm")
            assert fast.bits == pytest.approx(ref.bits, rel=1e-9, abs=1e-9)
            # never below the Lagrangian bound of its own prices: a certified upper bound
            phi = dual_bounds(reach, buf, 1.0, n_slots, fast.lam)[last]
            assert fast.bits >= phi - 1e-12 * max(1.0, phi)


def test_columns_equal_full_on_the_benchmark_path() -> None:
    # 300 samples of a lawnmower over 16 sensors (the bench_bound.py geometry, smaller)
    s = np.linspace(0.0, 1.0, 300)
    track = np.column_stack([1000.0 * np.abs(np.sin(9.0 * s)), 1000.0 * s])
    ticks = (np.arange(4) + 0.5) * 250.0
    sensors = np.array([(x, y) for x in ticks for y in ticks])
    dist = np.hypot(np.linalg.norm(track[:, None] - sensors[None], axis=2), 100.0)
    rate = 1e5 * np.log2(1.0 + 100.0 / (dist / 100.0) ** 2)
    buf = np.resize([8.75e6, 14e6, 12.25e6, 17.5e6], 16)
    for hover in (True, False):
        fast = fixed_path_bound(rate, buf, 1.0, 300, hover_allowed=hover)
        full = fixed_path_bound(rate, buf, 1.0, 300, hover_allowed=hover, solver="full")
        assert fast.upper_bound_bit == pytest.approx(full.upper_bound_bit, rel=1e-7)
        collected = np.sum(rate * fast.served_time_s, axis=0)
        assert 0 < np.sum(collected >= buf * (1 - 1e-6)) < 16  # time and some buffers bind


@pytest.mark.parametrize("preset", ["paper-sim-fixed", "aadm-default"])
@pytest.mark.parametrize("n_slots", [None, 150])
@pytest.mark.parametrize("hover", [True, False])
def test_columns_equal_full_on_presets(preset: str, n_slots: int | None, hover: bool) -> None:
    mission = preset_mission(preset)
    args = (mission_track_rates(mission), mission.buffers_bit, mission.slot_s)
    slots = n_slots or mission.n_slots
    fast = fixed_path_bound(*args, slots, hover_allowed=hover)
    full = fixed_path_bound(*args, slots, hover_allowed=hover, solver="full")
    assert fast.upper_bound_bit == pytest.approx(full.upper_bound_bit, rel=1e-7)


def test_unknown_solver_is_one_line() -> None:
    with pytest.raises(BoundError, match="solver must be one of") as info:
        fixed_path_bound(np.ones((2, 1)), np.ones(1), 1.0, 2, solver="fast")
    assert "\n" not in str(info.value)
