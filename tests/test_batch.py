"""The batched engine agrees with the reference engine value for value."""

from __future__ import annotations

import math
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skymule.experiments.run import _flat_summary, run_chunk
from skymule.experiments.sweep import iter_missions, load_sweep
from skymule.flight.paths import Track
from skymule.metrics import handover_counts, summarize
from skymule.policies import make_policy
from skymule.radio.rates import Shannon
from skymule.runner import simulate
from skymule.scenario import PolicySpec, load_scenario, scenario_from_dict
from skymule.sim.batch import (
    batchable,
    run_fixed_batch,
    summarize_fixed_batch,
)
from skymule.sim.engine import run_fixed
from skymule.flights import MissionLog
from skymule.sim.run import run_mission
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
        assert summarize(log, "x") == reference


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


# --- vectorised summaries (no MissionLog) and per-slot fading ------------------------------


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


def with_geometry(missions, geometry):
    return [replace(m, **geo) for m, geo in zip(missions, geometry, strict=True)]


def with_random_fading(mission, rng: np.random.Generator):
    """Half the time: per-slot fading (T, N) [dB]; a third of those on a Shannon rate table."""
    if rng.random() < 0.5:
        return mission
    fading = rng.normal(0, 6, (mission.n_slots, mission.n_sensors))
    mission = replace(mission, fading_db=fading)
    return replace(mission, rate_table=Shannon()) if rng.random() < 0.3 else mission


def reference_summary(mission, spec, name: str = "x") -> dict:
    return summarize(run_fixed(mission, make_policy(spec)), name)


def assert_summaries_equal(got: dict, want: dict) -> None:
    """Field for field, exactly: same keys in the same order, same types, same values (NaN=NaN)."""
    assert list(got) == list(want)
    for key, value in want.items():
        assert type(got[key]) is type(value), key
        if isinstance(value, float) and np.isnan(value):
            assert np.isnan(got[key]), key
        else:
            assert got[key] == value, (key, got[key], value)


def check_summaries(missions, specs, batch_size: int = 7) -> None:
    names = [f"m{i}" for i in range(len(missions))]
    got = summarize_fixed_batch(missions, specs, names, batch_size=batch_size)
    for row, mission, spec, name in zip(got, missions, specs, names, strict=True):
        assert_summaries_equal(row, reference_summary(mission, spec, name))


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**32 - 1), n_missions=st.integers(1, 12), n_sensors=st.integers(1, 5))
def test_vectorised_summaries_equal_summarize_on_random_missions(
    base_mission, seed, n_missions, n_sensors
):
    rng = np.random.default_rng(seed)
    missions = [
        with_random_fading(random_mission(base_mission, rng, n_sensors), rng)
        for _ in range(n_missions)
    ]
    specs = [random_spec(rng) for _ in range(n_missions)]
    geometry = [random_geometry(rng, n_sensors) for _ in range(n_missions)]
    missions = with_geometry(missions, geometry)
    check_summaries(missions, specs)
    check_equal(missions, specs)  # the logs of fading missions too


def test_vectorised_summaries_with_mixed_sensor_counts_and_shared_tracks(base_mission):
    rng = np.random.default_rng(11)
    missions = [random_mission(base_mission, rng, int(rng.integers(1, 9))) for _ in range(20)]
    # missions sharing a track (and rate table) with other buffers, slot counts and lengths
    missions += [
        replace(m, buffers_bit=m.buffers_bit[::-1].copy(), n_slots=int(rng.integers(1, 60)))
        for m in missions[:10]
    ]
    specs = [random_spec(rng) for _ in missions]
    geometry = [random_geometry(rng, m.n_sensors) for m in missions]
    for mission, geo in zip(missions[::2], geometry[::2], strict=True):
        if geo["hover_points_m"] is not None:  # home near the track's end: within and beyond
            geo["home_m"] = mission.track.position_m[-1, :2] + rng.normal(0, 2, 2)  # 3 m
    check_summaries(with_geometry(missions, geometry), specs, batch_size=6)


def test_vectorised_summaries_equal_summarize_on_paper_preset(base_mission):
    rng = np.random.default_rng(5)
    missions, specs = [], []
    for index in range(8):
        buffers = rng.uniform(0, 1500e6, base_mission.n_sensors)
        if index == 7:
            buffers[:] = [1e6, 2e6, 0.0, 3e6]  # emptied early: the AADM completion bonus
        missions.append(replace(base_mission, buffers_bit=buffers))
        specs.append(PolicySpec(name=("greedy", "hgad")[index % 2]))
    check_summaries(missions, specs, batch_size=1000)
    # and as ``skymule run`` gives them
    (row,) = summarize_fixed_batch(missions[:1], specs[:1], ["x"])
    assert_summaries_equal(row, summarize(run_mission(missions[0], make_policy(specs[0])), "x"))


@pytest.fixture(scope="module")
def rician_mission():
    scenario = load_scenario("paper-sim-fixed")
    radio = scenario.radio.model_copy(update={"fading": "rician"})
    return build_mission(scenario.model_copy(update={"radio": radio}))


def test_batched_engine_runs_rician_fading_like_the_reference(rician_mission):
    assert rician_mission.fading_db is not None
    assert batchable(rician_mission, PolicySpec(name="hgad"))
    rng = np.random.default_rng(9)
    missions = [
        replace(rician_mission, buffers_bit=rng.uniform(0, 1500e6, rician_mission.n_sensors))
        for _ in range(4)
    ]
    specs = [PolicySpec(name=name) for name in ("greedy", "hgad", "greedy", "hgad")]
    check_equal(missions, specs)
    check_summaries(missions, specs)
    # fading changes what happens: the faded run differs from the unfaded one
    plain = replace(missions[1], fading_db=None)
    (faded_log, plain_log) = run_fixed_batch([missions[1], plain], [specs[1]] * 2)
    assert not np.array_equal(faded_log.downloaded_bit, plain_log.downloaded_bit)


FADING_SWEEP = """
base = "paper-sim-fixed"
seed = 4
[axes]
policy.name = ["greedy", "hgad"]
radio.fading = ["none", "rician"]
seed = { range = [0, 2] }
"sensors[*].buffer_mbit" = { dist = "uniform", low = 20, high = 300 }
"mission.duration_s" = [90]
"""


def test_sweep_rows_from_vectorised_summaries_equal_skymule_run(tmp_path):
    """A sweep worker's rows (batched, fading included) are ``skymule run``'s summaries."""
    path = tmp_path / "sweep.toml"
    path.write_text(FADING_SWEEP)
    spec = load_sweep(path)
    missions = list(iter_missions(spec))
    tasks = [(m.index, m.mission_id, m.params, m.scenario) for m in missions]
    frame = run_chunk(tasks, str(tmp_path))
    assert len(frame) == 8
    for row, mission in zip(frame.to_dict("records"), missions, strict=True):
        scenario = scenario_from_dict(mission.scenario, "t", Path("."))
        want = _flat_summary(simulate(scenario).summary)
        for key, value in want.items():
            got = row[key]
            nan = isinstance(value, float) and math.isnan(value)
            assert (isinstance(got, float) and math.isnan(got)) if nan else got == value, key


def handovers(served) -> int:
    """Plain reference: changes of served sensor over the slots that served one."""
    changes, previous = 0, None
    for sensor in served:
        if sensor == -1:
            continue
        changes += previous is not None and sensor != previous
        previous = sensor
    return changes


def test_handover_counts_with_gaps_in_service_equal_metrics():
    """The general path (served slots not a prefix; Greedy/HGAD never leave such gaps)."""
    rng = np.random.default_rng(2)
    served = rng.choice([-1, -1, 0, 1, 2], size=(30, 200))  # (T, B) slot-major
    want = [handovers(served[:, b]) for b in range(served.shape[1])]
    np.testing.assert_array_equal(handover_counts(served), want)
    prefix = np.where(np.arange(30)[:, None] < rng.integers(0, 31, 200), served % 3, -1)
    want = [handovers(prefix[:, b]) for b in range(prefix.shape[1])]
    np.testing.assert_array_equal(handover_counts(prefix), want)
