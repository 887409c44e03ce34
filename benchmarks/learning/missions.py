"""The missions the ``learned`` policy trains and is measured on, drawn from seeded generators.

Training randomises what a deployed UAV may meet: layouts around the Lake Wheeler fence
(:func:`skymule.experiments.layouts.random_autonomous_scenario`: home, sensors within 300 m of
the fence, buffers, antenna heights, mission length, speed), the sensor count (3..8), the
channel (path-loss model, log-normal shadowing, Rician or Rayleigh fading) and faults (tower
outages, SNR measurement error, bursty link loss). Held-out missions come from other seeds.

The learned twin of sim-to-real, once it exists as a channel skymule can build, is one more
entry of :data:`CHANNELS` (its uncertainty one more per-sensor feature).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.scenario import Scenario, load_scenario, scenario_from_dict
from skymule.world import Mission, build_mission

#: The site every mission flies at (its fence, origin, link budget and home rules).
BASE = "paper-sim-autonomous"

#: Channels drawn for training: path-loss model and its parameters.
CHANNELS: tuple[dict[str, Any], ...] = (
    {"model": "fspl"},
    {"model": "two-ray"},
    {"model": "al-hourani"},
    {"model": "3gpp-rma-av"},
)

#: Shadowing standard deviations [dB] and fading kinds drawn for training; the shadowing
#: field decorrelates over SHADOWING_DECORRELATION_M (a field at 50 m costs a mission build
#: several times its flight).
SHADOWING_DB = (0.0, 0.0, 0.0, 0.0, 4.0, 8.0)
SHADOWING_DECORRELATION_M = 150.0
FADING = ("none", "none", "rician", "rayleigh")

#: The faults of the measured "with faults" condition (as ``benchmarks/bench_resilience.py``):
#: one random outage per tower (mean 60 s) and a 6 dB SNR measurement error.
EVAL_FAULTS: tuple[dict[str, Any], ...] = (
    {"kind": "outage", "params": {"mean_duration_s": 60.0}},
    {"kind": "snr-error", "params": {"std_db": 6.0, "correlation_s": 3.0}},
)

#: Fault sets drawn for training (with probability ``fault_probability``).
TRAIN_FAULTS: tuple[tuple[dict[str, Any], ...], ...] = (
    EVAL_FAULTS,
    ({"kind": "outage", "params": {"mean_duration_s": 60.0}},),
    ({"kind": "snr-error", "params": {"std_db": 6.0, "correlation_s": 3.0}},),
    ({"kind": "gilbert-elliott", "params": {"p_good_to_bad": 0.02, "p_bad_to_good": 0.2}},),
)


@dataclass(frozen=True)
class Draw:
    """How missions are drawn.

    Attributes:
        duration_s: (low, high) mission time [s].
        buffer_mbit: (low, high) buffer per sensor [Mbit].
        channels: draw channel models, shadowing and fading (else the base's free space).
        fault_probability: chance of a fault set (0: none; 1: :data:`EVAL_FAULTS` always
            when ``eval_faults``).
        eval_faults: the faults are :data:`EVAL_FAULTS` (measurements), else one of
            :data:`TRAIN_FAULTS`.
    """

    duration_s: tuple[int, int] = (200, 450)
    buffer_mbit: tuple[float, float] = (300.0, 1500.0)
    channels: bool = True
    fault_probability: float = 0.3
    eval_faults: bool = False


#: Training: everything randomised.
TRAINING = Draw()

#: The issue's measurement: 300-s missions, buffers the UAV cannot empty, free space.
HELD_OUT = Draw(duration_s=(300, 300), channels=False, fault_probability=0.0)

#: The same with faults.
HELD_OUT_FAULTS = Draw(
    duration_s=(300, 300), channels=False, fault_probability=1.0, eval_faults=True
)


def draw_scenario(rng: np.random.Generator, base: Scenario, n_sensors: int, draw: Draw) -> Scenario:
    """One random mission with ``n_sensors`` sensors (every draw from ``rng``)."""
    ranges = LayoutRanges(
        n_sensors=(n_sensors, n_sensors),
        buffer_mbit=draw.buffer_mbit,
        duration_s=draw.duration_s,
        draw_seed=True,
    )
    scenario = random_autonomous_scenario(rng, base, ranges)
    data = scenario.to_toml_dict()
    if draw.channels:
        radio = dict(data["radio"])
        radio.update(CHANNELS[int(rng.integers(len(CHANNELS)))])
        radio["shadowing_std_db"] = float(SHADOWING_DB[int(rng.integers(len(SHADOWING_DB)))])
        radio["shadowing_decorrelation_m"] = SHADOWING_DECORRELATION_M
        radio["fading"] = FADING[int(rng.integers(len(FADING)))]
        data["radio"] = radio
    if rng.random() < draw.fault_probability:
        faults = (
            EVAL_FAULTS if draw.eval_faults else TRAIN_FAULTS[int(rng.integers(len(TRAIN_FAULTS)))]
        )
        data["faults"] = [dict(f) for f in faults]
    return scenario_from_dict(data, scenario.name, Path(base.base_dir))


def draw_missions(seed: int, n_sensors: int, count: int, draw: Draw) -> list[Mission]:
    """``count`` built missions with ``n_sensors`` sensors from ``seed``."""
    rng = np.random.default_rng([seed, n_sensors])
    base = load_scenario(BASE)
    return [build_mission(draw_scenario(rng, base, n_sensors, draw)) for _ in range(count)]
