"""The batched engine agrees with the reference engine value for value."""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skymule.engine import MissionLog, run_fixed, run_mission
from skymule.engine_autonomous import fixed_geometry_fields
from skymule.engine_batch import run_fixed_batch
from skymule.flight.paths import Track
from skymule.metrics import summarize
from skymule.policies import make_policy
from skymule.scenario import PolicySpec, load_scenario
from skymule.world import build_mission


@pytest.fixture(scope="module")
def base_mission():
    return build_mission(load_scenario("paper-sim-fixed"))


def random_mission(base, rng: np.random.Generator, n_sensors: int):
    """A mission with a random track: quantised SNR (rate ties), NaN and low SNR (rate 0)."""
    n_samples = int(rng.integers(1, 40))
    snr = rng.choice([-20.0, -5.0, 3.0, 9.0, 12.0, 25.0], size=(n_samples, n_sensors))
    snr += rng.choice([0.0, 0.0, 0.1], size=snr.shape)  # SNR ties and near-ties
    snr[rng.random(snr.shape) < 0.1] = np.nan
    position = np.cumsum(rng.normal(0, 10, (n_samples, 3)), axis=0)
    track = Track(position_m=position, snr_db=snr, hold_at_end=bool(rng.integers(2)))
    buffers = rng.choice([0.0, 1e5, 1e6, 3e6, 2e7], size=n_sensors) * rng.random(n_sensors)
    buffers[rng.random(n_sensors) < 0.3] = rng.choice([0.0, 1.4e6 * 2.41, 2.1e6])
    names = tuple(f"S{i}" for i in range(n_sensors))
    return replace(
        base,
        sensor_names=names,
        sensor_m=np.zeros((n_sensors, 3)),
        buffers_bit=buffers,
        n_slots=int(rng.integers(1, 60)),
        slot_s=float(rng.choice([1.0, 0.5, 2.0])),
        track=track,
    )


def random_spec(rng: np.random.Generator) -> PolicySpec:
    return PolicySpec(
        name=str(rng.choice(["greedy", "hgad"])),
        hover_threshold=float(rng.choice([1.0, 0.5, 0.8, rng.uniform(0.05, 1.0)])),
        max_hover_s=float(rng.choice([60.0, 1.0, 2.5, 5.0])),
    )


def assert_logs_equal(batched: MissionLog, reference: MissionLog) -> None:
    for field in fields(MissionLog):
        got, want = getattr(batched, field.name), getattr(reference, field.name)
        if isinstance(want, np.ndarray):
            assert got.dtype == want.dtype, field.name
            np.testing.assert_array_equal(got, want, err_msg=field.name, strict=True)
        else:
            assert got == want, field.name


def check_equal(missions, specs) -> None:
    logs = run_fixed_batch(missions, specs, batch_size=7)
    for log, mission, spec in zip(logs, missions, specs, strict=True):
        assert_logs_equal(log, run_fixed(mission, make_policy(spec)))


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**32 - 1), n_missions=st.integers(1, 12), n_sensors=st.integers(1, 5))
def test_batched_equals_reference_on_random_missions(base_mission, seed, n_missions, n_sensors):
    rng = np.random.default_rng(seed)
    missions = [random_mission(base_mission, rng, n_sensors) for _ in range(n_missions)]
    specs = [random_spec(rng) for _ in range(n_missions)]
    check_equal(missions, specs)


def test_batched_equals_reference_with_mixed_sensor_counts(base_mission):
    rng = np.random.default_rng(7)
    missions = [random_mission(base_mission, rng, int(rng.integers(1, 5))) for _ in range(30)]
    specs = [random_spec(rng) for _ in range(30)]
    logs = run_fixed_batch(missions, specs, batch_size=4)
    for mission, spec, log in zip(missions, specs, logs, strict=True):
        assert_logs_equal(log, run_fixed(mission, make_policy(spec)))


def test_batched_equals_reference_on_paper_preset(base_mission):
    rng = np.random.default_rng(3)
    missions, specs = [], []
    for _ in range(6):
        buffers = rng.uniform(0, 1500e6, base_mission.n_sensors)
        missions.append(replace(base_mission, buffers_bit=buffers))
        specs.append(random_spec(rng))
    specs[0] = PolicySpec(name="hgad")
    specs[1] = PolicySpec(name="greedy")
    check_equal(missions, specs)
    # the summaries users see: the batched log + the mission's geometry, through summarize
    logs = run_fixed_batch(missions, specs)
    for log, mission, spec in zip(logs, missions, specs, strict=True):
        reference = summarize(run_mission(mission, make_policy(spec)), "x")
        assert summarize(replace(log, **fixed_geometry_fields(mission)), "x") == reference


def test_hgad_hovers_and_greedy_does_not_on_paper_preset(base_mission):
    specs = [PolicySpec(name="greedy"), PolicySpec(name="hgad")]
    greedy, hgad = run_fixed_batch([base_mission, base_mission], specs)
    assert not greedy.hovering.any()
    assert hgad.hovering.any()
    assert greedy.downloaded_bit.sum() > 0


def test_trace_ends_when_uav_moves_past_last_sample(base_mission):
    track = Track(np.zeros((3, 3)), np.full((3, 1), 30.0), hold_at_end=False)
    mission = replace(
        base_mission,
        sensor_names=("A",),
        sensor_m=np.zeros((1, 3)),
        buffers_bit=np.array([1e9]),
        n_slots=10,
        track=track,
    )
    (log,) = run_fixed_batch([mission], [PolicySpec(name="greedy")])
    assert log.n_slots == 3
    held = replace(mission, track=replace(track, hold_at_end=True))
    (log,) = run_fixed_batch([held], [PolicySpec(name="greedy")])
    assert log.n_slots == 10
