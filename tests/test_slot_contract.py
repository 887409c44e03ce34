"""Greedy and HGAD against hand-worked cases and the slot contract's invariants."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skymule.flight.paths import Track
from skymule.metrics.flights import NO_SENSOR
from skymule.policies import HGAD, Greedy, make_policy
from skymule.scenario import load_scenario
from skymule.sim.run import run_mission
from skymule.tasks.simulate import simulate
from skymule.world import mission_from_track

# Two sensors A, B over a ten-sample trace. With bandwidth 1 MHz the AADM table gives rates
# in Mbit/s equal to the spectral efficiency: 23 dB -> 5.55, 15 dB -> 3.32, 6 dB -> 1.48,
# -10 dB -> 0.
HAND_SNR_DB = np.array(
    [
        [23, 6],
        [23, 15],
        [15, 23],
        [6, 23],
        [-10, 23],
        [-10, 15],
        [6, 6],
        [23, -10],
        [23, -10],
        [15, -10],
    ],
    float,
)
HAND_BUFFERS_MBIT = [30.0, 20.0]


def _write_dt_trace(path: Path, snr_db: np.ndarray) -> Path:
    lines = ["Time,A,B,X,Y,Height"]
    for k, (a, b) in enumerate(snr_db):
        lines.append(f"{k},{a:g},{b:g},{10 * k},0,30")
    path.write_text("\n".join(lines) + "\n")
    return path


def _hand_scenario(tmp_path: Path, policy: str) -> Path:
    trace = _write_dt_trace(tmp_path / "hand.csv", HAND_SNR_DB)
    text = f"""
name = "hand"
[mission]
slot_s = 1.0
[[sensors]]
name = "A"
buffer_mbit = {HAND_BUFFERS_MBIT[0]}
[[sensors]]
name = "B"
buffer_mbit = {HAND_BUFFERS_MBIT[1]}
[radio]
bandwidth_hz = 1e6
[signal]
source = "trace"
trace = "{trace.name}"
[policy]
name = "{policy}"
"""
    scenario = tmp_path / "hand.toml"
    scenario.write_text(text)
    return scenario


def test_greedy_hand_case(tmp_path: Path) -> None:
    result = simulate(load_scenario(_hand_scenario(tmp_path, "greedy")))
    log = result.log
    # worked by hand: argmax SNR among sensors with data, ties to the lower index (slot 6)
    assert log.served.tolist() == [0, 0, 1, 1, 1, 1, 0, 0, 0, 0]
    expected = [5.55, 5.55, 5.55, 5.55, 5.55, 3.32, 1.48, 5.55, 5.55, 3.32]
    np.testing.assert_allclose(log.downloaded_bit / 1e6, expected, atol=1e-9)
    np.testing.assert_allclose(log.remaining_bit[-1] / 1e6, [3.00, 0.03], atol=1e-9)
    assert not log.hovering.any()
    assert result.summary["handovers"] == 2
    assert result.summary["total_downloaded_mbit"] == pytest.approx(46.97)


def test_hgad_hand_case(tmp_path: Path) -> None:
    result = simulate(load_scenario(_hand_scenario(tmp_path, "hgad")))
    log = result.log
    # slot 0: A at its peak 5.55 triggers a hover with budget 24.45/5.55 = 4.41 s, which runs
    # out in slot 5 (A empties there too); A then cools down; B is served on the move and
    # triggers at its peak in slot 8 (budget 9.65/5.55 = 1.74 s).
    assert log.served.tolist() == [0, 0, 0, 0, 0, 0, 1, 1, 1, 1]
    expected = [5.55, 5.55, 5.55, 5.55, 5.55, 2.25, 1.48, 3.32, 5.55, 5.55]
    np.testing.assert_allclose(log.downloaded_bit / 1e6, expected, atol=1e-9)
    assert log.hovering.astype(int).tolist() == [1, 1, 1, 1, 1, 1, 0, 0, 1, 1]
    # the UAV held sample 0 for slots 0..6, then moved one sample per non-hover slot
    np.testing.assert_allclose(log.position_m[:, 0], [0, 0, 0, 0, 0, 0, 0, 10, 20, 20])
    np.testing.assert_allclose(log.remaining_bit[-1] / 1e6, [0.0, 4.10], atol=1e-9)
    assert result.summary["handovers"] == 1
    assert result.summary["hover_time_s"] == 8.0


def test_trace_ends_when_used_up_unless_hovering(tmp_path: Path) -> None:
    scenario = load_scenario(_hand_scenario(tmp_path, "greedy"))
    longer = scenario.model_copy(
        update={"mission": scenario.mission.model_copy(update={"duration_s": 40.0})}
    )
    greedy = simulate(longer).log
    assert greedy.n_slots == len(HAND_SNR_DB)  # one sample per slot, then the trace is used up
    hgad = simulate(longer, "hgad").log
    # every non-hover slot consumes one sample: slots = samples + hover slots
    assert hgad.n_slots == len(HAND_SNR_DB) + int(hgad.hovering.sum())


def test_planned_path_holds_at_end() -> None:
    track = Track(np.array([[0.0, 0, 30], [10, 0, 30]]), np.array([[23.0], [23.0]]), True)
    mission = mission_from_track(track, [1000.0], n_slots=5, policy="greedy")
    log = run_mission(mission, Greedy())
    assert log.n_slots == 5
    np.testing.assert_allclose(log.position_m[:, 0], [0, 10, 10, 10, 10])


def test_greedy_and_hgad_on_the_paper_preset() -> None:
    scenario = load_scenario("paper-sim-fixed")
    greedy = simulate(scenario, "greedy").summary
    hgad = simulate(scenario, "hgad").summary
    for summary in (greedy, hgad):
        assert summary["slots"] == 500
        assert 0 < summary["total_downloaded_mbit"] <= 3000
    # the paper's finding on its simulated fixed path: HGAD collects more than Greedy
    assert hgad["total_downloaded_mbit"] > greedy["total_downloaded_mbit"]
    assert hgad["handovers"] <= greedy["handovers"]


@st.composite
def random_missions(draw: st.DrawFn) -> tuple:
    n_sensors = draw(st.integers(1, 4))
    n_samples = draw(st.integers(1, 25))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    snr = rng.uniform(-15, 30, size=(n_samples, n_sensors)).round(0)  # rounding makes ties
    snr[rng.random(snr.shape) < 0.1] = np.nan
    buffers = rng.choice([0.0, 1.0, 5.0, 20.0, 100.0], size=n_sensors)
    hold = draw(st.booleans())
    track = Track(
        np.column_stack([np.arange(n_samples) * 10.0, np.zeros((n_samples, 2))]), snr, hold
    )
    n_slots = draw(st.integers(1, 60))
    threshold = draw(st.sampled_from([1.0, 0.8, 0.5]))
    max_hover = draw(st.sampled_from([1.0, 2.5, 5.0, 60.0]))
    slot_s = draw(st.sampled_from([1.0, 0.5]))
    return track, buffers, n_slots, threshold, max_hover, slot_s


@settings(max_examples=150, deadline=None)
@given(random_missions(), st.sampled_from(["greedy", "hgad"]))
def test_invariants_on_random_missions(case: tuple, policy_name: str) -> None:
    track, buffers, n_slots, threshold, max_hover, slot_s = case
    mission = mission_from_track(
        track,
        buffers,
        n_slots=n_slots,
        slot_s=slot_s,
        policy=policy_name,
        hover_threshold=threshold,
        max_hover_s=max_hover,
    )
    log = run_mission(mission, make_policy(mission.scenario.policy))
    start = np.vstack([mission.buffers_bit, log.remaining_bit[:-1]]) if log.n_slots else None
    assert log.n_slots <= n_slots
    assert (log.remaining_bit >= 0).all()
    if log.n_slots:
        decrement = start - log.remaining_bit
        # only the served sensor's buffer changes, by exactly what was downloaded
        for t in range(log.n_slots):
            changed = np.flatnonzero(decrement[t] != 0)
            assert set(changed.tolist()) <= ({int(log.served[t])} - {NO_SENSOR})
        np.testing.assert_allclose(decrement.sum(axis=1), log.downloaded_bit, rtol=0, atol=1e-6)
        # y = min(R dt, Q)
        served = log.served != NO_SENSOR
        rate = log.rate_bps[served, log.served[served]]
        np.testing.assert_allclose(
            log.downloaded_bit[served],
            np.minimum(rate * slot_s, start[served, log.served[served]]),
        )
    if policy_name == "greedy":
        assert not log.hovering.any()
    # a hover episode (trigger slot + hover slots) lasts at most max_hover_s after the trigger
    # (an episode on another sensor may start right after one ends: split on the sensor)
    longest = run = 0
    previous = NO_SENSOR
    for hovering, sensor in zip(log.hovering, log.served, strict=True):
        run = run + 1 if hovering and sensor == previous and run else int(hovering)
        previous = sensor if hovering else NO_SENSOR
        longest = max(longest, run)
    assert longest <= 1 + int(np.ceil(max_hover / slot_s - 1e-9))


def test_policies_keep_no_state_between_missions() -> None:
    track = Track(np.zeros((3, 3)), np.array([[23.0, 6], [23, 6], [6, 23]]), True)
    mission = mission_from_track(track, [20.0, 20.0], n_slots=8)
    policy = HGAD()
    first = run_mission(mission, policy)
    second = run_mission(mission, policy)
    np.testing.assert_array_equal(first.served, second.served)
    np.testing.assert_array_equal(first.downloaded_bit, second.downloaded_bit)


@pytest.mark.parametrize("preset", ["paper-sim-fixed", "paper-sim-autonomous"])
def test_the_download_window_closes_like_the_aadm_controller(preset: str) -> None:
    """``aadm_window_s``: slots that start at or after the window serve nothing."""
    scenario = load_scenario(preset)
    closed = scenario.model_copy(
        update={"mission": scenario.mission.model_copy(update={"aadm_window_s": 100.5})}
    )
    open_log = simulate(scenario, "hgad").log
    log = simulate(closed, "hgad").log
    assert (log.served[101:] == NO_SENSOR).all() and not log.downloaded_bit[101:].any()
    np.testing.assert_array_equal(log.downloaded_bit[:101], open_log.downloaded_bit[:101])
    assert log.downloaded_bit.sum() < open_log.downloaded_bit.sum()


def test_first_true_is_the_first_sensor_down_each_column() -> None:
    """Ties in the choices go to the lowest sensor index: the first True of each column, 0
    where a column has none (the callers mark those NO_SENSOR)."""
    from skymule.rules.contract import first_true

    rng = np.random.default_rng(3)
    for n_sensors in (1, 2, 5, 17):
        mask = rng.random((n_sensors, 64)) < rng.uniform(0.0, 0.5)
        want = [int(np.flatnonzero(col)[0]) if col.any() else 0 for col in mask.T]
        assert first_true(mask).tolist() == want
    assert first_true(np.zeros((0, 3), bool)).tolist() == [0, 0, 0]
