"""The vectorised metrics equal a plain, slot-by-slot reading of the same mission log.

``metrics.summaries`` is the one implementation (the batched engine and ``summarize`` both use
it); the reference here is written the slow, obvious way, one loop per metric, so that a
change in the vectorised code that alters a number fails here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skymule.energy import propulsion_power_w
from skymule.metrics.flights import NO_SENSOR, MissionLog, flight_record
from skymule.metrics.summary import summarize


def random_log(rng: np.random.Generator, autonomous: bool) -> MissionLog:
    """A self-consistent log: downloads follow y = min(R dt, Q); hovering slots stay put."""
    n_sensors, n_slots = int(rng.integers(1, 5)), int(rng.integers(0, 40))
    slot_s = float(rng.choice([0.5, 1.0, 2.0]))
    buffers = rng.choice([0.0, 2e6, 1e7, 5e7], size=n_sensors)
    rate = rng.choice([0.0, 1e6, 4e6, 8e6], size=(n_slots, n_sensors))
    served = rng.integers(-1, n_sensors, n_slots)
    hovering = rng.random(n_slots) < 0.3
    left = buffers.copy()
    downloaded = np.zeros(n_slots)
    remaining = np.zeros((n_slots, n_sensors))
    positions = np.zeros((n_slots + 1, 3))
    for t in range(n_slots):
        if served[t] != NO_SENSOR:
            downloaded[t] = min(rate[t, served[t]] * slot_s, left[served[t]])
            left[served[t]] -= downloaded[t]
        remaining[t] = left
        step = np.zeros(3) if hovering[t] else rng.normal(0, 8, 3)
        positions[t + 1] = positions[t] + step
    hover_points = rng.normal(0, 20, (n_sensors, 2))
    hover_points[rng.random(n_sensors) < 0.2] = np.nan
    return MissionLog(
        flight_record(
            policy="p",
            sensor_names=tuple(f"S{i}" for i in range(n_sensors)),
            slot_s=slot_s,
            buffers_bit=buffers,
            position_m=positions[:-1],
            end_position_m=positions[-1],
            snr_db=np.zeros((n_slots, n_sensors)),
            rate_bps=rate,
            served=served,
            downloaded_bit=downloaded,
            remaining_bit=remaining,
            hovering=hovering,
            home_m=None if rng.random() < 0.2 else positions[-1, :2] + rng.normal(0, 3, 2),
            hover_points_m=None if rng.random() < 0.1 else hover_points,
            visit_radius_m=float(rng.choice([5.0, 20.0])),
            target=rng.integers(-1, n_sensors, n_slots) if autonomous else None,
        )
    )


def plain_visit_order(log: MissionLog) -> list[str]:
    first: dict[int, int] = {}
    known = log.hover_points_m is not None and not np.isnan(log.hover_points_m).all()
    after = [*log.position_m[1:], log.end_position_m]
    hovered_any = any(log.hovering[t] and log.served[t] != NO_SENSOR for t in range(log.n_slots))
    for t in range(log.n_slots):
        for i in range(len(log.sensor_names)):
            if i in first:
                continue
            if log.target is not None and known:
                near = math.dist(after[t][:2], log.hover_points_m[i]) <= log.visit_radius_m
                hit = near and log.target[t] == i
            elif hovered_any:
                hit = bool(log.hovering[t]) and log.served[t] == i
            elif log.hover_points_m is not None:
                hit = math.dist(log.position_m[t][:2], log.hover_points_m[i]) <= log.visit_radius_m
            else:
                hit = False
            if hit:
                first[i] = t
    return [log.sensor_names[i] for i in sorted(first, key=lambda i: (first[i], i))]


def plain_summary(log: MissionLog) -> dict[str, float | int | bool | list[str]]:
    total_buffer = float(sum(log.buffers_bit))
    total = float(sum(log.downloaded_bit))
    path = [*log.position_m, log.end_position_m]
    steps = [
        0.0 if log.hovering[t] else math.dist(path[t], path[t + 1]) for t in range(log.n_slots)
    ]
    power = [float(propulsion_power_w(np.array(s / log.slot_s))) for s in steps]
    handovers, previous = 0, None
    for sensor in log.served:
        if sensor != NO_SENSOR:
            handovers += previous is not None and sensor != previous
            previous = sensor
    # AADM rule in force: downloads count in slots starting before the 500 s window; S1 =
    # 500 - t1 when all data arrived by t1, S2 = 100 x downloaded / total; no landing term
    counted, t1 = 0.0, None
    for t in range(log.n_slots):
        if t * log.slot_s < 500.0 - 1e-9:
            counted += log.downloaded_bit[t]
            if t1 is None and total_buffer > 0 and counted >= total_buffer * (1 - 1e-9):
                t1 = (t + 1) * log.slot_s
    if total_buffer <= 0:
        t1 = 0.0
    s2 = 100.0 * min(counted, total_buffer) / total_buffer if total_buffer > 0 else 100.0
    score = s2 + (max(0.0, 500.0 - t1) if t1 is not None else 0.0)
    to_home = float("nan")
    if log.home_m is not None:
        to_home = math.dist(log.end_position_m[:2], log.home_m)
    return {
        "total_downloaded_mbit": total / 1e6,
        "completion": total / total_buffer if total_buffer > 0 else 1.0,
        "handovers": handovers,
        "hover_time_s": sum(bool(h) for h in log.hovering) * log.slot_s,
        "distance_m": sum(steps),
        "energy_kj": sum(power) * log.slot_s / 1e3,
        "visit_order": plain_visit_order(log),
        "distance_to_home_m": to_home,
        "aadm_score": score,
    }


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), autonomous=st.booleans())
def test_summaries_equal_a_plain_reading_of_the_log(seed: int, autonomous: bool) -> None:
    log = random_log(np.random.default_rng(seed), autonomous)
    got = summarize(log, "x")
    for key, want in plain_summary(log).items():
        if isinstance(want, float) and math.isnan(want):
            assert math.isnan(got[key]), key
        elif isinstance(want, float):
            assert got[key] == pytest.approx(want, rel=1e-12, abs=1e-9), key
        else:
            assert got[key] == want, key
