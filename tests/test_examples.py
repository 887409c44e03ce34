"""The example files in examples/ load and run as their comments say."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from skymule.io.traces import write_aadm_log, write_dt_export
from skymule.scenario import load_scenario
from skymule.tasks.simulate import simulate

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
NAMES = ("LW1", "LW2", "LW3", "LW4")


def _synthetic_flight(path: Path, n_samples: int, digital_twin: bool) -> None:
    rng = np.random.default_rng(7)
    time_s = np.arange(n_samples, dtype=float)
    snr_db = rng.uniform(-10, 30, size=(n_samples, 4)).round(1)
    x_m = np.linspace(-300, 100, n_samples)
    y_m = np.linspace(-200, 200, n_samples)
    z_m = np.full(n_samples, 25.0)
    if digital_twin:
        write_dt_export(path, time_s, snr_db, NAMES, x_m, y_m, z_m)
    else:
        lat = 35.7274824 + y_m / 111_000.0
        lon = -78.6962749 + x_m / 90_000.0
        write_aadm_log(path, time_s, snr_db, NAMES, lat, lon, z_m)


@pytest.mark.parametrize(
    ("example", "digital_twin", "buffers"),
    [
        ("paper-dt-fixed", True, [500, 800, 700, 1000]),
        ("paper-rw-flight1", False, [500, 800, 700, 1000]),
        ("paper-rw-flight2", False, [1500, 1300, 1100, 200]),
    ],
)
def test_paper_trace_templates_replay_a_flight(
    tmp_path: Path, example: str, digital_twin: bool, buffers: list[int]
) -> None:
    scenario_path = tmp_path / f"{example}.toml"
    shutil.copy(EXAMPLES / f"{example}.toml", scenario_path)
    scenario = load_scenario(scenario_path)
    assert [s.buffer_mbit for s in scenario.sensors] == buffers  # the paper's Table I
    assert scenario.signal.trace is not None
    _synthetic_flight(tmp_path / scenario.signal.trace, 120, digital_twin)
    for policy in ("greedy", "hgad"):
        summary = simulate(scenario, policy).summary
        assert summary["slots"] >= 120 if policy == "hgad" else summary["slots"] == 120
        assert 0 < summary["total_downloaded_mbit"] <= sum(buffers)


def test_sweep_example_parses() -> None:
    from skymule.experiments.sweep import load_sweep

    spec = load_sweep(EXAMPLES / "sweep-paper.toml")
    assert spec.base.name == "paper-sim-fixed"
    assert {axis.key for axis in spec.axes} >= {"policy.name", "seed"}
