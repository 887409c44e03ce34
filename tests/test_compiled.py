"""The compiled twin equals the numpy rules: kernels vs contract, the compiled slot loop vs
the numpy slot loop of the fixed-trajectory engine.

Every check runs without numba too: the kernels and the loop are plain Python that numba
compiles, so where it is absent they run as they are (slowly, on small cases), and where it
is installed the compiled loop is checked as well.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine_cases import (
    TWIN_RTOL,
    assert_logs_equal,
    assert_summaries_equal,
    random_mission,
    random_spec,
)
from skymule.errors import SkymuleError
from skymule.policies import batch_policy
from skymule.radio.rates import BUILTIN_RATE_TABLES, StepTable, rate_bps
from skymule.rules import contract
from skymule.scenario import PolicySpec
from skymule.sim import compiled, kernels
from skymule.sim.batch_faults import BatchFaults, apply_faults, kernel_faults
from skymule.sim.fixed import FixedEngine, compiled_reason, run_compiled
from skymule.sim.run import run_missions, summarize_missions

needs_numba = pytest.mark.skipif(not compiled.available(), reason="numba not installed")


def random_columns(rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    """(rate, snr, remaining) for one mission: ties, zeros, -inf, NaN and empty buffers."""
    rate = rng.choice([0.0, 1e6, 2e6, 2e6, 5e6, np.nan], size=n)
    snr = rng.choice([-np.inf, -3.0, 4.0, 4.0, 12.0, np.nan], size=n)
    remaining = rng.choice([0.0, 0.0, 1.0, 3e6], size=n)
    return rate, snr, remaining


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6))
def test_choice_kernels_equal_contract(seed, n):
    rng = np.random.default_rng(seed)
    rate, snr, remaining = random_columns(rng, n)
    has_data = contract.servable(rate[:, None], remaining[:, None])
    want_greedy = contract.greedy_choice(snr[:, None], has_data)[0]
    want_hgad = contract.hgad_choice(rate[:, None], snr[:, None], has_data)[0]
    assert kernels.greedy_pick(snr, rate, remaining) == want_greedy
    assert kernels.hgad_pick(rate, snr, remaining) == want_hgad


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), hgad=st.booleans())
def test_hover_kernel_equals_contract_over_a_run(seed, n, hgad):
    """Serve through a random run of slots with both; the hover state stays equal."""
    rng = np.random.default_rng(seed)
    threshold = rng.choice([0.0, 1e6, 4e6], size=n)
    peak = rng.choice([0.0, 2e6, 5e6], size=n)
    max_hover, dt = float(rng.choice([1.0, 2.5, 60.0])), float(rng.choice([0.5, 1.0]))
    remaining = rng.choice([0.0, 2e6, 2e7], size=n)
    state = contract.HoverState.start(n, 1)
    hover, cooling = np.array([contract.NO_SENSOR, 0.0]), np.zeros(n, bool)
    for _ in range(30):
        rate = rng.choice([0.0, 1e6, 3e6, 5e6], size=n)
        choice = contract.hgad_choice(rate[:, None], rate[:, None], remaining[:, None] > 0)
        sensor = int(contract.hover_sensor_or(state, choice)[0])
        bits = contract.served_bits(rate[sensor], remaining[sensor], dt) if sensor >= 0 else 0.0
        remaining[max(sensor, 0)] -= bits
        want = contract.hgad_update(
            state,
            sensor=np.array([sensor]),
            cell=contract.cells(np.array([sensor])),
            rate_bps=rate[:, None],
            rate_served_bps=np.array([rate[max(sensor, 0)]]),
            left_after_bit=np.array([remaining[max(sensor, 0)]]),
            threshold_bps=threshold,
            peak_rate_bps=peak,
            max_hover_s=np.array([max_hover]),
            slot_s=np.array([dt]),
            enabled=hgad,
        )[0]
        got = kernels.hgad_hover_step(
            hover, cooling, sensor, rate, remaining[max(sensor, 0)], threshold, peak,
            max_hover, dt, hgad,
        )  # fmt: skip
        assert got == want
        assert (hover[0], hover[1]) == (state.sensor[0], state.budget_s[0])
        np.testing.assert_array_equal(cooling, state.cooling)


def test_step_rate_equals_the_rate_table_at_and_around_every_threshold():
    table = BUILTIN_RATE_TABLES["aadm-lte-cqi"]
    assert isinstance(table, StepTable)
    thresholds = np.array(table.thresholds_db)
    snr = np.concatenate(
        [thresholds, np.nextafter(thresholds, -np.inf), [-np.inf, np.inf, np.nan, -40.0, 40.0]]
    )
    efficiency = np.concatenate([[0.0], table.efficiencies])
    got = [kernels.step_rate(value, thresholds, efficiency, 1.4e6) for value in snr]
    np.testing.assert_array_equal(got, rate_bps(table, snr, 1.4e6))


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), uses_error=st.booleans())
def test_fault_kernels_equal_apply_faults(seed, n, uses_error):
    """One mission's slot under faults: what the policy sees and what serving delivers, on
    the AADM step table (SNR at and around its thresholds, -inf, NaN-free as in the batch)."""
    rng = np.random.default_rng(seed)
    table = BUILTIN_RATE_TABLES["aadm-lte-cqi"]
    assert isinstance(table, StepTable)
    steps = rng.choice(table.thresholds_db, size=n)
    snr = np.where(rng.random(n) < 0.2, -np.inf, steps + rng.choice([-0.1, 0.0, 0.1, 30.0], n))
    rate = rate_bps(table, snr, 1.4e6)
    error = rng.choice([0.0, -2.3, 0.5, 4.0], size=n) if uses_error else np.zeros(n)
    ok = rng.random(n) < 0.7
    faults = BatchFaults(
        index=np.array([0]),
        deliverable=ok[None, None, :],
        snr_error_db=error[None, None, :],
        rate_model=np.array([0]),
        rate_models=((table, 1.4e6),),
    )
    want = apply_faults(faults, 0, rate[:, None], snr[:, None])
    kernel = kernel_faults(faults, 1)
    assert kernel is not None
    track_rate, track_snr = np.stack([rate * 0.5, rate]), np.stack([snr - 1.0, snr])  # row 1
    got = np.empty(n), np.empty(n), np.empty(n)
    kernels.fault_view(
        track_rate, track_snr, 1, faults.deliverable[0], faults.snr_error_db[0], 0,
        bool(kernel.uses_error[0]), kernel.thresholds_db[0], kernel.efficiency[0],
        float(kernel.bandwidth_hz[0]), *got,
    )  # fmt: skip
    for ours, theirs in zip(got, want[:3], strict=True):
        np.testing.assert_array_equal(ours, theirs[:, 0], strict=True)


def loops() -> list[object]:
    """The loops to check against numpy: the plain-Python loop always, the compiled one
    where numba is installed."""
    return [compiled.slot_loop, *([compiled.compiled_loop()] if compiled.available() else [])]


def assert_loops_equal_numpy(missions, specs) -> None:
    """Record for record (per-slot detail included), the numpy slot loop and each loop."""
    want = run_missions(missions, batch_policy(specs), engine="numpy")
    for loop in loops():
        engine = FixedEngine(missions)
        policy = batch_policy(specs)
        policy.reset(engine.contexts())
        rule = policy.slot_rule()  # type: ignore[attr-defined]
        got = run_compiled(engine, rule, [s.name for s in specs], loop=loop)
        for b in range(len(missions)):
            assert_logs_equal(got.mission(b), want.mission(b))


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**32 - 1), n_missions=st.integers(1, 12), n_sensors=st.integers(1, 5))
def test_compiled_loop_equals_numpy_loop(base_mission, seed, n_missions, n_sensors):
    """Random tracks, buffers, windows and HGAD parameters; Greedy and HGAD in one batch."""
    rng = np.random.default_rng(seed)
    missions = [random_mission(base_mission, rng, n_sensors) for _ in range(n_missions)]
    assert_loops_equal_numpy(missions, [random_spec(rng) for _ in range(n_missions)])


@needs_numba
def test_compiled_summaries_equal_numpy_on_paper_preset(base_mission):
    rng = np.random.default_rng(5)
    missions = [replace(base_mission, buffers_bit=rng.uniform(0, 1500e6, 4)) for _ in range(20)]
    specs = [PolicySpec(name="greedy"), PolicySpec(name="hgad", max_hover_s=20.0)] * 10
    names = ["paper"] * 20
    numpy_rows = summarize_missions(missions, specs, names, engine="numpy")
    got = summarize_missions(missions, specs, names, engine="compiled")
    assert_summaries_equal(got, numpy_rows, TWIN_RTOL)
    assert any(row["hover_time_s"] > 0 for row in numpy_rows)


def test_compiled_refuses_what_it_cannot_run(base_mission):
    """Fading, and a policy without a compiled twin: one line; ``auto`` runs numpy."""
    faded = replace(base_mission, fading_db=np.zeros((base_mission.n_slots, 4)))
    engine = FixedEngine([faded])
    policy = batch_policy([PolicySpec(name="greedy")])
    policy.reset(engine.contexts())
    reason = compiled_reason(engine, policy.slot_rule())  # type: ignore[attr-defined]
    assert reason is not None and ("per-slot fading" in reason or "numba" in reason)
    with pytest.raises(SkymuleError, match="cannot run this batch"):
        run_missions([faded], batch_policy([PolicySpec(name="greedy")]), engine="compiled")
    flights = run_missions([faded], batch_policy([PolicySpec(name="greedy")]))  # auto
    assert flights.n_run[0] == base_mission.n_slots
    robust = batch_policy([PolicySpec(name="hgad-robust")])
    with pytest.raises(SkymuleError, match="no compiled twin"):
        run_missions([base_mission], robust, engine="compiled")


def test_auto_without_numba_runs_numpy(base_mission, monkeypatch):
    hgad = [PolicySpec(name="hgad")]
    want = run_missions([base_mission], batch_policy(hgad), engine="numpy")
    monkeypatch.setattr(compiled, "available", lambda: False)
    assert_logs_equal(run_missions([base_mission], batch_policy(hgad)).mission(0), want.mission(0))
    with pytest.raises(SkymuleError, match="numba is not installed"):
        run_missions([base_mission], batch_policy(hgad), engine="compiled")


def test_unknown_engine_is_one_line(base_mission):
    with pytest.raises(SkymuleError, match="engine = 'fast'; allowed: auto, numpy, compiled"):
        run_missions([base_mission], batch_policy([PolicySpec(name="greedy")]), engine="fast")
