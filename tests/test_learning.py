"""Training ``learned``: the missions, the ES pieces, and that stacked models fly as each alone."""

from __future__ import annotations

import numpy as np
import pytest

from learning.es import centred_ranks, downloads, fitness, relative_gain
from learning.missions import HELD_OUT_FAULTS, TRAINING, draw_missions
from skymule.policies.learned import LearnedPolicy, OptionNet, initial_net
from skymule.sim.run import run_missions


def test_ranks_and_fitness() -> None:
    ranks = centred_ranks(np.array([3.0, -1.0, 7.0, 0.5]))
    np.testing.assert_allclose(ranks, [1 / 6, -0.5, 0.5, -1 / 6])
    gain = np.array([[0.05, 0.05], [0.10, -0.10]])  # same mean, the second loses 10 % once
    score = fitness(gain, margin=0.02, weight=4.0)
    assert score[0] == pytest.approx(0.05)
    assert score[1] == pytest.approx(0.0 - 4.0 * 0.08 / 2)
    np.testing.assert_allclose(relative_gain(np.array([110.0, 0.0]), np.array([100.0, 0.0])),
                               [0.1, 0.0])  # fmt: skip


def test_missions_are_seeded_and_randomised() -> None:
    a = draw_missions(3, 5, 4, TRAINING)
    b = draw_missions(3, 5, 4, TRAINING)
    assert [m.n_sensors for m in a] == [5] * 4
    np.testing.assert_array_equal([m.buffers_bit for m in a], [m.buffers_bit for m in b])
    faulty = draw_missions(3, 4, 2, HELD_OUT_FAULTS)
    assert all(m.faults is not None for m in faulty)
    assert {m.n_slots for m in faulty} == {300}


def test_stacked_models_fly_as_each_model_alone() -> None:
    missions = draw_missions(4, 3, 3, TRAINING)
    rng = np.random.default_rng(1)
    first, second = initial_net(rng), initial_net(rng)
    second = second.with_flat(second.flat() + 0.3 * rng.standard_normal(second.flat().shape))
    stacked = first.with_flat(np.concatenate([first.flat(), second.flat()]))
    together = downloads(missions, stacked)
    for index, net in enumerate((first, second)):
        alone = run_missions(missions, LearnedPolicy(net), detail=False).downloaded_bit
        np.testing.assert_array_equal(together[index], alone.sum(axis=1))


def test_a_ppo_update_keeps_the_weights_finite() -> None:
    torch = pytest.importorskip("torch", reason="the PPO comparison needs the rl extra")
    from learning.es import hgad_downloads
    from learning.ppo import PPOConfig, TorchScorer, _update, rollout

    missions = draw_missions(5, 3, 3, TRAINING)
    rng = np.random.default_rng(0)
    model = TorchScorer(initial_net(rng))
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)
    before = model.to_net().flat()
    data, _ = rollout(model, missions, hgad_downloads(missions), rng)
    assert len(data["action"]) > 0 and np.isfinite(data["return"]).all()
    _update(model, optimizer, [data], PPOConfig(minibatch=8), rng)
    after = model.to_net().flat()
    assert np.isfinite(after).all() and not np.array_equal(before, after)


def test_fine_tuning_keeps_the_start_unless_a_validated_centre_beats_it() -> None:
    from learning.es import ESConfig, train_es

    start = initial_net(np.random.default_rng(2))
    config = ESConfig(pairs=2, missions_per_count=2, pool_per_count=2, sensor_counts=(3,),
                      workers=1, teacher="planner")  # fmt: skip

    def only_the_start(net: OptionNet) -> dict[str, float]:
        return {"score": 1.0 if np.array_equal(net.flat(), start.flat()) else -1.0}

    kept = train_es(config, 600.0, only_the_start, 1, 2, lambda _: None, start_net=start)
    np.testing.assert_array_equal(kept.net.flat(), start.flat())
    assert len(kept.curve) == 2 and all(row["score"] == -1.0 for row in kept.curve)

    def any_change(net: OptionNet) -> dict[str, float]:
        return {"score": 0.0 if np.array_equal(net.flat(), start.flat()) else 1.0}

    moved = train_es(config, 600.0, any_change, 1, 2, lambda _: None, start_net=start)
    assert not np.array_equal(moved.net.flat(), start.flat())


def test_an_unknown_teacher_is_refused() -> None:
    from learning.es import reference_downloads

    with pytest.raises(ValueError, match="teacher = 'greedy'; allowed: hgad, planner"):
        reference_downloads(draw_missions(1, 3, 1, TRAINING), "greedy")
