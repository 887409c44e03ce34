"""``learned``: the option scorer shipped as plain weights, run in numpy on the engine."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import preset_mission
from skymule.errors import SkymuleError
from skymule.policies import batch_policy, make_policy
from skymule.policies.learned import (
    FEATURE_NAMES,
    FORMAT,
    LearnedPolicy,
    initial_net,
    load_net,
    save_net,
    scores,
    shipped_weights,
)
from skymule.policies.options import N_DURATIONS, Decision, OptionRunner
from skymule.scenario import PolicySpec, Scenario, load_scenario
from skymule.sim.run import run_mission, run_missions
from skymule.world import Mission, build_mission


def short(duration_s: float = 150.0) -> Scenario:
    base = load_scenario("paper-sim-autonomous")
    return base.model_copy(
        update={"mission": base.mission.model_copy(update={"duration_s": duration_s})}
    )


@pytest.fixture(scope="module")
def random_missions() -> list[Mission]:
    from learning.missions import HELD_OUT, draw_missions

    return draw_missions(5, 4, 6, HELD_OUT)


def test_the_shipped_model_runs_without_torch() -> None:
    code = (
        "import sys; from skymule.policies import make_policy; from skymule.scenario import "
        "PolicySpec, load_scenario; from skymule.sim.run import run_mission; "
        "from skymule.world import build_mission; "
        "log = run_mission(build_mission(load_scenario('paper-sim-autonomous')), "
        "make_policy(PolicySpec(name='learned'))); "
        "assert 'torch' not in sys.modules and 'stable_baselines3' not in sys.modules; "
        "print(round(log.downloaded_bit.sum() / 1e6, 1))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert float(done.stdout.strip()) > 1000.0  # of the preset's 3000 Mbit


def test_the_shipped_weights_are_plain_arrays() -> None:
    with zipfile.ZipFile(shipped_weights()) as archive:
        names = sorted(archive.namelist())
    net = load_net(shipped_weights())  # allow_pickle=False inside: an object array would fail
    assert net.models == 1
    assert "features.npy" in names and "format.npy" in names


def test_the_policy_flies_home_in_time_serving_by_options() -> None:
    mission = build_mission(short())
    policy = make_policy(PolicySpec(name="learned"))
    log = run_mission(mission, policy)
    assert log.downloaded_bit.sum() > 0
    np.testing.assert_allclose(log.end_position_m[:2], mission.home_m, atol=1e-6)
    # options, not slots: a handful of decisions over 150 slots
    runner = policy.runner  # type: ignore[union-attr]
    assert 1 <= runner.decisions <= 30
    # while hovering the UAV serves the sensor it hovers for
    hovering = log.hovering & (log.target >= 0)
    assert hovering.any()
    assert (log.served[hovering] == log.target[hovering]).mean() > 0.9


def test_one_batch_equals_each_mission_alone(random_missions: list[Mission]) -> None:
    policy = make_policy(PolicySpec(name="learned"))
    together = run_missions(random_missions, policy, detail=False).downloaded_bit.sum(axis=1)
    alone = [
        run_mission(m, make_policy(PolicySpec(name="learned"))).downloaded_bit.sum()
        for m in random_missions
    ]
    np.testing.assert_array_equal(together, alone)


def test_sweeps_batch_the_learned_policy_once(random_missions: list[Mission]) -> None:
    specs = [PolicySpec(name="learned")] * len(random_missions)
    assert isinstance(batch_policy(specs), LearnedPolicy)


def _decision(rng: np.random.Generator, n: int) -> Decision:
    rows = np.arange(3)
    peak = rng.uniform(1e6, 8e6, (3, n))
    remaining = rng.uniform(0, 1e9, (3, n))
    remaining[0, 0] = 0.0
    pair = rng.integers(0, 60, (3, n, n)).astype(float)
    pair = pair + pair.transpose(0, 2, 1)
    pair[:, np.arange(n), np.arange(n)] = 0.0
    return Decision(
        rows=rows,
        travel=rng.integers(0, 60, (3, n)).astype(float),
        back=rng.integers(0, 60, (3, n)).astype(float),
        pair=pair,
        home=rng.integers(0, 60, 3).astype(float),
        slots_left=np.array([300.0, 120.0, 40.0]),
        n_slots=np.full(3, 300.0),
        slot_s=np.ones(3),
        remaining=remaining,
        initial=remaining + 1e8,
        peak=peak,
        rate_now=peak * rng.uniform(0, 1, (3, n)),
        usable=remaining > 0,
        visited=rng.random((3, n)) < 0.3,
        near=rng.random((3, n)) < 0.2,
    )


@pytest.mark.parametrize("n", [3, 5, 8])
def test_scores_follow_the_sensors_whatever_their_order(n: int) -> None:
    rng = np.random.default_rng(n)
    net = load_net(shipped_weights())
    decision = _decision(rng, n)
    order = rng.permutation(n)
    fields = ("travel", "back", "remaining", "initial", "peak", "rate_now", "usable", "visited",
              "near")  # fmt: skip
    permuted = Decision(
        **{
            name: (getattr(decision, name)[:, order] if name in fields else value)
            for name, value in vars(decision).items()
        }
        | {"pair": decision.pair[:, order][:, :, order]}
    )
    width = N_DURATIONS
    a, b = scores(net, None, decision), scores(net, None, permuted)
    a_opts = a[:, :-1].reshape(3, n, width)[:, order]
    np.testing.assert_allclose(b[:, :-1].reshape(3, n, width), a_opts, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(a[:, -1], b[:, -1], rtol=1e-12)
    assert np.isneginf(a[0, :width]).all()  # no data: no option of sensor 0
    assert np.isfinite(a[:, -1]).all()  # going home is always allowed


def test_stacked_models_score_as_each_model_alone() -> None:
    rng = np.random.default_rng(0)
    one, two = initial_net(rng), initial_net(rng)
    stacked = one.with_flat(np.concatenate([one.flat(), two.flat()]))
    decision = _decision(rng, 4)
    model = np.array([1, 0, 1])
    together = scores(stacked, model, decision)
    for row, m in enumerate(model):
        alone = scores(stacked.model(int(m)), None, decision)[row]
        np.testing.assert_allclose(together[row], alone, rtol=1e-12, atol=1e-12)


def test_one_model_serves_any_sensor_count() -> None:
    base = short()
    policy = make_policy(PolicySpec(name="learned"))
    for count in (3, 4):
        scenario = base.model_copy(update={"sensors": base.sensors[:count]})
        assert run_mission(build_mission(scenario), policy).downloaded_bit.sum() > 0


def test_own_weights_load_by_path(tmp_path: Path) -> None:
    net = initial_net(np.random.default_rng(3))
    path = save_net(net, tmp_path / "mine.npz")
    assert not list(tmp_path.glob(".*"))  # the temporary name is gone
    policy = make_policy(PolicySpec(name=f"learned:{path}"))
    assert policy.name == "learned:mine"
    loaded = load_net(path)
    np.testing.assert_array_equal(loaded.flat(), net.flat())
    log = run_mission(build_mission(short()), policy)
    assert log.downloaded_bit.sum() > 0


def _write(path: Path, **arrays: np.ndarray) -> Path:
    with path.open("wb") as handle:
        np.savez(handle, **arrays)
    return path


def _valid_arrays() -> dict[str, np.ndarray]:
    net = initial_net(np.random.default_rng(0))
    arrays = {name: value[0] for name, value in vars(net).items()}
    return {"format": np.array(FORMAT), "features": np.array(FEATURE_NAMES), **arrays}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda a: a.pop("home_w"), "missing home_w"),
        (lambda a: a.update(extra=np.zeros(2)), "unexpected extra"),
        (lambda a: a.update(hidden_w=np.zeros((3, 3))), r"hidden_w has shape \(3, 3\)"),
        (lambda a: a.update(out_b=np.array(np.nan)), "out_b holds NaN"),
        (lambda a: a.update(format=np.array("other")), "format is other"),
        (lambda a: a.update(features=np.array(["x"])), "other features"),
        (lambda a: a.update(out_w=np.array(["a"] * 32)), "out_w has dtype"),
    ],
)
def test_a_bad_weights_file_is_one_clear_error(
    tmp_path: Path, change: object, message: str
) -> None:
    arrays = _valid_arrays()
    change(arrays)  # type: ignore[operator]
    path = _write(tmp_path / "bad.npz", **arrays)
    with pytest.raises(SkymuleError, match=message) as info:
        make_policy(PolicySpec(name=f"learned:{path}"))
    assert "\n" not in str(info.value) and "bad.npz" in str(info.value)


def test_a_pickle_in_the_weights_is_refused_not_run(tmp_path: Path) -> None:
    arrays = _valid_arrays()
    arrays["out_w"] = np.array([object()] * 32, dtype=object)
    path = _write(tmp_path / "pickled.npz", **arrays)
    with pytest.raises(SkymuleError, match=r"not a readable \.npz of plain arrays"):
        load_net(path)


@pytest.mark.parametrize("content", [b"", b"not a zip", None])
def test_a_file_that_is_no_npz_is_one_clear_error(tmp_path: Path, content: bytes | None) -> None:
    path = tmp_path / "weights.npz"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(SkymuleError, match=r"weights\.npz"):
        load_net(path)


def test_the_cli_runs_learned_and_refuses_bad_weights(tmp_path: Path) -> None:
    from skymule.cli import main

    run = ["run", "paper-sim-autonomous", "--policy", "learned", "--set", "mission.duration_s=120"]
    assert main([*run, "--out", str(tmp_path / "run")]) in (0, None)
    assert (tmp_path / "run" / "summary.json").is_file()
    bad = tmp_path / "bad.npz"
    bad.write_text("x")
    done = subprocess.run(
        [sys.executable, "-m", "skymule", "run", "paper-sim-autonomous", "--policy",
         f"learned:{bad}", "--out", str(tmp_path / "bad-run")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert "bad.npz" in done.stderr + done.stdout


def test_fixed_paths_are_one_clear_error() -> None:
    mission = preset_mission("paper-sim-fixed")
    with pytest.raises(SkymuleError, match=r"trajectory\.mode = 'autonomous'"):
        run_mission(mission, make_policy(PolicySpec(name="learned")))


def test_the_runner_refuses_fixed_contexts() -> None:
    from skymule.sim.run import mission_context

    context = mission_context(preset_mission("paper-sim-fixed"))
    with pytest.raises(ValueError, match="autonomous"):
        OptionRunner([context], lambda d: np.zeros(len(d.rows), np.int64))


def test_the_torch_mirror_scores_as_numpy() -> None:
    torch = pytest.importorskip("torch", reason="the PPO comparison needs the rl extra")
    from learning.ppo import TorchScorer
    from skymule.policies.options import option_features

    net = load_net(shipped_weights())
    decision = _decision(np.random.default_rng(9), 6)
    model = TorchScorer(net)
    logits, _ = model(*(torch.as_tensor(f) for f in option_features(decision)))
    np.testing.assert_allclose(logits.detach().numpy(), scores(net, None, decision), rtol=1e-9)
    np.testing.assert_allclose(model.to_net().flat(), net.flat(), rtol=1e-12)


def test_the_aadm_loopback_flies_learned_as_skymule_run() -> None:
    from skymule.aadm.loopback import fly_loopback

    # the preset's own length: shorter missions differ from skymule run for HGAD too (the
    # loopback's climb before the volumes are shared)
    result = fly_loopback(load_scenario("paper-sim-autonomous"), "learned", poll_s=0.0)
    np.testing.assert_allclose(result.flight_mbit, result.engine_mbit, atol=1e-6)
    assert result.engine_mission_mbit > 0
    assert result.landed_distance_m <= 5.0


def test_a_fleet_flies_learned_uavs_on_shared_buffers() -> None:
    from skymule.scenario import UavSpec
    from skymule.tasks.fleet import simulate_fleet

    base = short(200.0)
    uavs = [UavSpec(name="A"), UavSpec(name="B", home=[-200.0, -100.0])]
    summary = simulate_fleet(base.model_copy(update={"uavs": uavs}), "learned").summary
    assert summary["total_downloaded_mbit"] > 0
    assert all(uav["landed_within_5m"] for uav in summary["uavs"])


@pytest.mark.parametrize("n", [3, 4, 8])
def test_the_compiled_twin_scores_as_numpy(n: int, monkeypatch: pytest.MonkeyPatch) -> None:
    from skymule.policies import learned_kernel
    from skymule.policies.learned import compiled_scores

    net = load_net(shipped_weights())
    decision = _decision(np.random.default_rng(n), n)
    expected = scores(net, None, decision)
    np.testing.assert_allclose(compiled_scores(net, decision), expected, rtol=1e-9, atol=1e-12)
    # and as plain Python (what runs without numba)
    monkeypatch.setattr(learned_kernel, "score_kernel", lambda: learned_kernel.score_rows)
    np.testing.assert_allclose(compiled_scores(net, decision), expected, rtol=1e-9, atol=1e-12)


def test_the_compiled_twins_tanh_is_the_librarys_to_round_off() -> None:
    from skymule.policies.learned_kernel import tanh
    from skymule.sim import compiled

    grid = np.concatenate([np.geomspace(1e-300, 1e300, 20_001), np.linspace(0.0, 40.0, 40_001)])
    values = np.concatenate([grid, -grid, [0.0, -0.0, np.inf, -np.inf]])
    forms: list[Any] = [tanh]  # plain Python (no numba), and compiled where numba is installed
    if compiled.available():
        import numba

        forms.append(numba.njit(tanh))
    for form in forms:
        ours = np.array([form(float(a)) for a in values])
        assert np.abs(ours - np.tanh(values)).max() <= 2.3e-16
        assert np.array_equal(np.signbit(ours), np.signbit(np.tanh(values)))
        assert np.isnan(form(float("nan")))


def test_numpy_and_compiled_scorers_fly_the_same_missions(random_missions: list[Mission]) -> None:
    policy = make_policy(PolicySpec(name="learned"))
    numpy_form = make_policy(PolicySpec(name="learned"))
    numpy_form._compiled = False  # type: ignore[union-attr]
    a = run_missions(random_missions, policy, detail=False).downloaded_bit
    b = run_missions(random_missions, numpy_form, detail=False).downloaded_bit
    np.testing.assert_array_equal(a, b)
