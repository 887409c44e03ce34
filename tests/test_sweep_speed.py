"""Sweeps that build missions, not scenarios: the quick path gives what full validation
gives, refuses what it refuses, batches plug-ins by content, and starts nothing for nothing."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from conftest import write
from skymule.errors import SkymuleError
from skymule.experiments import executors
from skymule.experiments import run as sweep_run
from skymule.experiments.run import allowed_values, run_sweep
from skymule.experiments.seeding import PCG64Rows, entropy_words
from skymule.experiments.sweep import SweepPlan, SweepSpec, load_sweep, parse_sweep, sweep_plan
from skymule.limits import MAX_BUFFER_MBIT, waypoint_problem
from skymule.tasks import simulate as single

PLUGINS = Path(__file__).parent / "plugins"

MIXED = """
base = "paper-sim-fixed"
seed = 5
mode = {{ sample = {n} }}
[axes]
policy.name = ["greedy", "hgad"]
"mission.duration_s" = [60, 90]
"radio.fading" = ["none", "rayleigh"]
seed = {{ dist = "integers", low = 0, high = 1000 }}
name = ["a", "b"]
"sensors[*].buffer_mbit" = {{ dist = "uniform", low = 20, high = 300 }}
"sensors[2].buffer_mbit" = [0, 150]
"""
"""Structures (policy, duration, fading), per-mission seeds (fading follows them), names, and
buffers from a distribution and a list on one sensor (applied after it)."""


def _spec(text: str, folder: Path = Path(".")) -> SweepSpec:
    return parse_sweep(tomllib.loads(text), "sweep.toml", folder)


def test_the_quick_path_gives_the_rows_of_full_validation() -> None:
    plan = sweep_plan(_spec(MIXED.format(n=12)))
    planned = list(plan.missions())
    quick = sweep_run._chunk_runs(plan.resolve, planned)
    assert quick is not None  # every value passes: one scenario per structure
    full = sweep_run._validated_runs(plan.resolve, planned)
    assert len({id(s.policy) for s in quick.scenarios}) <= 8  # policy x duration x fading
    for mine, theirs in zip(quick.scenarios, full.scenarios, strict=True):
        assert (mine.seed, mine.name, mine.policy, mine.radio) == (
            theirs.seed,
            theirs.name,
            theirs.policy,
            theirs.radio,
        )
    for got, want in zip(quick.buffers_bit, full.buffers_bit, strict=True):
        np.testing.assert_array_equal(got, want)
    pd.testing.assert_frame_equal(sweep_run._run(quick), sweep_run._run(full))


@pytest.mark.parametrize(
    ("axis", "said"),
    [  # the sweep file's check (one draw) passes; some mission's draw later fails
        ('"sensors[*].buffer_mbit" = { dist = "normal", mean = 200, std = 100 }', "buffer_mbit"),
        ('seed = { dist = "integers", low = -1, high = 4 }', "seed = -1"),
    ],
)
def test_a_bad_drawn_value_is_the_full_validations_one_line(
    tmp_path: Path, axis: str, said: str
) -> None:
    text = f'base = "paper-sim-fixed"\nmode = {{ sample = 60 }}\n[axes]\n{axis}\n'
    spec = load_sweep(write(tmp_path, text))
    with pytest.raises(SkymuleError) as error:
        run_sweep(spec, tmp_path / "out", executor="inprocess", progress=False)
    line = str(error.value)
    assert "\n" not in line and "(mission " in line and said in line, line


def test_allowed_values_reads_the_scenario_models_checks() -> None:
    assert allowed_values([0, 1.5, MAX_BUFFER_MBIT], "buffer_mbit")
    bad_buffers: list[list[Any]] = [[-1.0], [True], [np.nan], [2 * MAX_BUFFER_MBIT], ["5"]]
    for bad in [*bad_buffers, [np.float32(1)]]:
        assert not allowed_values(bad, "buffer_mbit"), bad
    assert allowed_values([0, 2**62], "seed")
    bad_seeds: list[list[Any]] = [[-1], [1.0], [2**63], [2**70], [False]]
    for bad in bad_seeds:
        assert not allowed_values(bad, "seed"), bad
    assert allowed_values(["a", ""], "name") and not allowed_values(["a", 1], "name")


def test_a_batched_plugin_without_params_runs_in_real_batches(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every mission has its own spec object: grouped by content, they share one instance
    (batches > 1), as a plug-in with Params does; reset once per batch."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    import batch_probe

    rows = {}
    for probe in (batch_probe.ServeFirstProbe, batch_probe.ServeFirstProbeWithParams):
        text = (
            f'base = "paper-sim-fixed"\nmode = {{ sample = 60 }}\n[axes]\n'
            f'policy.name = ["batch_probe:{probe.__name__}"]\n'
            '"sensors[*].buffer_mbit" = { dist = "uniform", low = 20, high = 300 }\n'
        )
        probe.calls.clear()
        spec = load_sweep(write(tmp_path, text, f"{probe.__name__}.toml"))
        out = run_sweep(spec, tmp_path / probe.__name__, executor="inprocess", progress=False)
        acts = [size for kind, size in probe.calls if kind == "act"]
        resets = [size for kind, size in probe.calls if kind == "reset"]
        assert set(acts) == {60} and resets == [60], probe.calls[:3]
        rows[probe] = out.results.sort_values("mission_index")["total_downloaded_mbit"]
    left, right = rows.values()
    np.testing.assert_array_equal(left.to_numpy(), right.to_numpy())


def test_a_finished_sweep_starts_no_executor(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    spec = _spec(MIXED.format(n=4))
    run_sweep(spec, tmp_path / "out", executor="inprocess", progress=False)
    opened = []
    real = executors.open_executor

    def record(name: str, *args: Any, **kwargs: Any) -> Any:
        opened.append(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(sweep_run, "open_executor", record)
    again = run_sweep(spec, tmp_path / "out", executor="dask-local", workers=2, progress=False)
    assert (again.n_run, again.n_missions, opened) == (0, len(spec), ["inprocess"])
    with pytest.raises(SkymuleError, match="allowed: inprocess"):
        run_sweep(spec, tmp_path / "out", executor="dask-locl", progress=False)


def test_one_mission_moves_to_the_compiled_engine_once_loading_it_has_paid(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(single, "_numpy_slots", [0])
    monkeypatch.setattr(single, "compiled_loaded", lambda: False)
    per = 500
    calls = -(-single.COMPILED_WORTH_SLOTS // per)  # the one that reaches the threshold last
    engines = [single.engine_for(per) for _ in range(calls)]
    assert engines == ["numpy"] * (calls - 1) + ["auto"]
    monkeypatch.setattr(single, "_numpy_slots", [0])
    monkeypatch.setattr(single, "compiled_loaded", lambda: True)
    assert single.engine_for(per) == "auto"  # loaded already: it costs nothing more


def test_waypoint_limits_name_the_first_bad_waypoint_and_axis() -> None:
    good = np.zeros((30, 3))
    assert waypoint_problem(good) is None
    late = good.copy()
    late[7, 2], late[9, 0] = np.nan, 1e8
    assert waypoint_problem(late) == (
        "waypoint 8: z_m = nan: allowed: 0 (the take-off ground) to 20000 m "
        "(above any UAV's ceiling; skymule's limit)"
    )
    both = good.copy()
    both[3, 1], both[3, 2] = -2e7, -1.0
    assert str(waypoint_problem(both)).startswith("waypoint 4: y_m = -20000000.0: at most 1e+07")


@pytest.mark.parametrize("seed", [0, 7, 2**40 + 3])
def test_generators_over_arrays_draw_what_numpy_draws(seed: int) -> None:
    replicas = [0, 1, 2, 1000, 2**31, 2**32 - 1]
    words = np.array([entropy_words(seed) + entropy_words(r) + [1] for r in replicas], np.uint32)
    got = PCG64Rows(words).uniform(-3.5, 1500, 5)
    want = [np.random.default_rng([seed, r, 1]).uniform(-3.5, 1500, 5) for r in replicas]
    np.testing.assert_array_equal(got, np.array(want))  # bit for bit, not approximately


def test_a_sampled_plan_draws_all_replicas_at_once_as_one_by_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    text = MIXED.format(n=40).replace(
        'seed = { dist = "integers", low = 0, high = 1000 }',
        '"sensors[1].x_m" = { dist = "uniform", low = -5, high = 5 }',
    )
    plan = sweep_plan(_spec(text))
    together = list(plan.missions(3, 71))
    monkeypatch.setattr(SweepPlan, "_uniform_draws", lambda self, replicas: None)
    assert together == list(plan.missions(3, 71))


def test_a_product_plan_draws_all_combinations_at_once_as_one_by_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    text = (
        'base = "paper-sim-fixed"\nseed = 3\n[axes]\npolicy.name = ["greedy", "hgad"]\n'
        'seed = { range = [0, 30] }\n"mission.duration_s" = [60, 90]\n'
        '"sensors[*].buffer_mbit" = { dist = "uniform", low = 20, high = 300 }\n'
    )
    plan = sweep_plan(_spec(text))
    together = list(plan.missions(5, 113))
    monkeypatch.setattr(SweepPlan, "_combination_draws", lambda self, keys: None)
    assert together == list(plan.missions(5, 113))
