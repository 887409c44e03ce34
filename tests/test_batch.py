"""The fixed-trajectory engine over a batch: every column is its own mission.

A mission gives the same log alone (a batch of one) and inside a batch of other missions,
other policies and other parameters; the batch's summaries are those of ``skymule run``.
The hand-worked cases of the slot contract are in ``tests/test_slot_contract.py``; the
compiled twin's equality in ``tests/test_compiled.py``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine_cases import (
    TWIN_RTOL,
    assert_logs_equal,
    assert_summaries_equal,
    random_geometry,
    random_mission,
    random_spec,
    with_geometry,
    with_random_fading,
)
from skymule.experiments.run import _flat_summary, run_chunk
from skymule.experiments.sweep import iter_missions, load_sweep
from skymule.flight.paths import Track
from skymule.metrics.summary import handover_counts, summarize
from skymule.policies import batch_policy
from skymule.scenario import PolicySpec, load_scenario, scenario_from_dict
from skymule.sim.run import run_mission, run_missions, summarize_missions
from skymule.tasks.simulate import simulate
from skymule.world import build_mission


def alone(mission, spec, engine: str = "numpy"):
    return run_mission(mission, batch_policy([spec]), engine=engine)


def check_batch_equals_alone(missions, specs, engine: str = "numpy") -> None:
    """One batch of the missions (one sensor count) equals each mission run alone."""
    flights = run_missions(missions, batch_policy(specs), engine=engine)
    for b, (mission, spec) in enumerate(zip(missions, specs, strict=True)):
        assert_logs_equal(flights.mission(b), alone(mission, spec, engine))


@settings(
    max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**32 - 1), n_missions=st.integers(1, 12), n_sensors=st.integers(1, 5))
def test_a_mission_alone_equals_it_inside_a_batch(base_mission, seed, n_missions, n_sensors):
    """Random tracks, buffers, windows, HGAD parameters, Greedy and HGAD mixed; half faded."""
    rng = np.random.default_rng(seed)
    missions = [
        with_random_fading(random_mission(base_mission, rng, n_sensors), rng)
        for _ in range(n_missions)
    ]
    check_batch_equals_alone(missions, [random_spec(rng) for _ in range(n_missions)])


def test_hgad_hovers_and_greedy_does_not_on_paper_preset(base_mission):
    specs = [PolicySpec(name="greedy"), PolicySpec(name="hgad")]
    greedy, hgad = run_missions([base_mission] * 2, batch_policy(specs)).missions()
    assert not greedy.hovering.any()
    assert hgad.hovering.any()
    assert greedy.downloaded_bit.sum() > 0
    assert (greedy.policy, hgad.policy) == ("greedy", "hgad")


def test_trace_ends_when_uav_moves_past_last_sample(base_mission):
    track = Track(np.zeros((3, 3)), np.full((3, 1), 30.0), hold_at_end=False)
    mission = replace(
        base_mission,
        sensor_names=("A",),
        sensor_m=np.zeros((1, 3)),
        buffers_bit=np.array([1e9]),
        n_slots=10,
        track=track,
        hover_points_m=None,
    )
    assert alone(mission, PolicySpec(name="greedy")).n_slots == 3
    held = replace(mission, track=replace(track, hold_at_end=True))
    assert alone(held, PolicySpec(name="greedy")).n_slots == 10


def test_summaries_of_a_batch_are_those_of_skymule_run(base_mission):
    """Random missions of several sensor counts sharing tracks, fading, geometry near the
    track's end: each row of ``summarize_missions`` (compiled where it can) is ``summarize``
    of the mission run alone, field for field."""
    rng = np.random.default_rng(11)
    missions = [
        with_random_fading(random_mission(base_mission, rng, int(rng.integers(1, 6))), rng)
        for _ in range(24)
    ]
    # missions sharing a track (and rate table) with other buffers, slot counts and lengths
    missions += [
        replace(m, buffers_bit=m.buffers_bit[::-1].copy(), n_slots=int(rng.integers(1, 60)))
        for m in missions[:10]
        if m.fading_db is None
    ]
    geometry = [random_geometry(rng, m.n_sensors) for m in missions]
    for mission, geo in zip(missions[::2], geometry[::2], strict=True):
        if geo["hover_points_m"] is not None:  # home near the track's end: within and beyond
            geo["home_m"] = mission.track.position_m[-1, :2] + rng.normal(0, 2, 2)
    missions = with_geometry(missions, geometry)
    specs = [random_spec(rng) for _ in missions]
    names = [f"m{i}" for i in range(len(missions))]
    for engine in ("numpy", "auto"):
        rows = summarize_missions(missions, specs, names, batch_size=6, engine=engine)
        for row, mission, spec, name in zip(rows, missions, specs, names, strict=True):
            assert_summaries_equal(row, summarize(alone(mission, spec), name), TWIN_RTOL)


def test_summaries_on_the_paper_preset(base_mission):
    rng = np.random.default_rng(5)
    missions, specs = [], []
    for index in range(8):
        buffers = rng.uniform(0, 1500e6, base_mission.n_sensors)
        if index == 7:
            buffers[:] = [1e6, 2e6, 0.0, 3e6]  # emptied early: the AADM completion bonus
        missions.append(replace(base_mission, buffers_bit=buffers))
        specs.append(PolicySpec(name=("greedy", "hgad")[index % 2]))
    rows = summarize_missions(missions, specs, ["x"] * 8)
    for row, mission, spec in zip(rows, missions, specs, strict=True):
        assert_summaries_equal(row, summarize(alone(mission, spec), "x"), TWIN_RTOL)
    assert rows[7]["aadm_complete"] and rows[1]["hover_time_s"] > 0


def test_rician_fading_changes_what_happens():
    scenario = load_scenario("paper-sim-fixed")
    radio = scenario.radio.model_copy(update={"fading": "rician"})
    faded = build_mission(scenario.model_copy(update={"radio": radio}))
    assert faded.fading_db is not None
    plain = replace(faded, fading_db=None)
    hgad = PolicySpec(name="hgad")
    flights = run_missions([faded, plain], batch_policy([hgad, hgad]))
    assert not np.array_equal(flights.downloaded_bit[0], flights.downloaded_bit[1])
    # the observed SNR is the track's plus that slot's fading
    log = flights.mission(0)
    np.testing.assert_allclose(
        log.snr_db, faded.track.snr_db[flights.sample[0, : log.n_slots]] + faded.fading_db
    )


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


def test_sweep_rows_equal_skymule_run(tmp_path):
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
        assert_summaries_equal({key: row[key] for key in want}, want, TWIN_RTOL)


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


def test_batches_share_a_mode_and_sensor_count_and_stay_within_memory() -> None:
    """batch_groups: one batch per (mode, sensor count), longest mission first, and a batch of
    long missions is cut to what BATCH_MEMORY_BYTES holds (a user's hour-long missions do
    not fill memory at the default of 4,096 a batch)."""
    from types import SimpleNamespace

    from skymule.sim.run import BATCH_MEMORY_BYTES, batch_bytes, batch_groups

    def mission(mode: str, n_sensors: int, n_slots: int) -> SimpleNamespace:
        return SimpleNamespace(mode=mode, n_sensors=n_sensors, n_slots=n_slots, navigator=None)

    short = [mission("fixed", 4, 500 - i % 3) for i in range(5)] + [mission("fixed", 3, 500)]
    groups = list(batch_groups(short, 4096))
    assert groups == [[0, 3, 1, 4, 2], [5]]  # 500, 500, 499, 499, 498 slots; then N = 3
    assert [len(g) for g in batch_groups(short, 2)] == [2, 2, 1, 1]
    long_slots = 360_000  # 100 h at 1 s
    per_batch = BATCH_MEMORY_BYTES // batch_bytes(long_slots, 8)
    long = [mission("autonomous", 8, long_slots) for _ in range(per_batch + 1)]
    assert [len(g) for g in batch_groups(long, 4096)] == [per_batch, 1]
