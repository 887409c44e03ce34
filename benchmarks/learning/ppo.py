"""PPO on the same options, features and network as the ES trainer (needs torch: ``rl`` extra).

The comparison ``benchmarks/train_learned.py --algorithm ppo`` measures against ES. A decision
is one step of a semi-Markov decision process: the agent samples an option from the softmax
of the network's scores (:func:`skymule.policies.learned.scores`, mirrored in torch), the
engine flies it, and the decision's return is everything downloaded from then to the end of
the mission (undiscounted), divided by HGAD's download on the same mission. A critic on the
pooled mission features estimates it; the policy follows the clipped surrogate objective
(Schulman et al., "Proximal Policy Optimization Algorithms", 2017) over minibatches of
decisions of one sensor count at a time. The network starts from the same prior as ES
(:func:`~skymule.policies.learned.initial_net`) and is saved in the same weights format.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import nn

from learning.es import Pool
from learning.missions import TRAINING, Draw
from skymule.policies.learned import FG, FO, FS, OptionNet, initial_net
from skymule.policies.options import N_DURATIONS, Decision, OptionRunner, option_features
from skymule.sim.autonomous import AutonomousEngine


@dataclass(frozen=True)
class PPOConfig:
    """PPO settings."""

    missions_per_batch: int = 48
    pool_per_count: int = 120
    sensor_counts: tuple[int, ...] = (3, 4, 5, 6, 7, 8)
    counts_per_iteration: int = 2
    epochs: int = 4
    minibatch: int = 256
    learning_rate: float = 3e-4
    clip: float = 0.2
    value_weight: float = 0.5
    entropy_weight: float = 0.003
    hidden: int = 16
    width: int = 32
    seed: int = 0
    draw: Draw = field(default=TRAINING)


class TorchScorer(nn.Module):
    """:func:`skymule.policies.learned.scores` in torch, plus a critic."""

    def __init__(self, net: OptionNet) -> None:
        super().__init__()
        hidden, width = net.sizes
        self.encoder = nn.Linear(FS + FG, hidden)
        self.hidden = nn.Linear(FS + FO + FG + 2 * hidden, width)
        self.out = nn.Linear(width, 1)
        self.linear = nn.Linear(FS + FO + FG, 1, bias=False)
        self.home = nn.Linear(FG + 2 * hidden, 1)
        self.critic = nn.Sequential(nn.Linear(FG + 2 * hidden, 32), nn.Tanh(), nn.Linear(32, 1))
        self.double()  # the numpy scorer's floats, exactly
        with torch.no_grad():
            for layer, w, b in (
                (self.encoder, net.encoder_w[0].T, net.encoder_b[0]),
                (self.hidden, net.hidden_w[0].T, net.hidden_b[0]),
                (self.out, net.out_w[0][None], net.out_b[0:1]),
                (self.home, net.home_w[0][None], net.home_b[0:1]),
            ):
                layer.weight.copy_(torch.as_tensor(w))
                layer.bias.copy_(torch.as_tensor(b))
            self.linear.weight.copy_(torch.as_tensor(net.linear_w[0][None]))

    def forward(
        self,
        sensor: torch.Tensor,
        option: torch.Tensor,
        mission: torch.Tensor,
        allowed: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(R, N*D + 1) logits (-inf where not allowed) and (R,) values."""
        rows, n = sensor.shape[:2]
        width = N_DURATIONS
        usable = allowed[:, :-1].reshape(rows, n, width).any(dim=2)
        enc = torch.tanh(self.encoder(torch.cat([sensor, mission[:, None].expand(rows, n, FG)], 2)))
        count = usable.sum(dim=1, keepdim=True)
        mean = (enc * usable[..., None]).sum(dim=1) / count.clamp(min=1)
        top = torch.where(usable[..., None], enc, torch.full_like(enc, -1.0)).max(dim=1).values
        top = torch.where(count > 0, top, torch.zeros_like(top))
        pooled = torch.cat([mean, top], dim=1)
        x = torch.cat(
            [
                sensor[:, :, None].expand(rows, n, width, FS),
                option,
                mission[:, None, None].expand(rows, n, width, FG),
            ],
            dim=3,
        )
        xp = torch.cat([x, pooled[:, None, None].expand(rows, n, width, pooled.shape[1])], 3)
        value = self.out(torch.tanh(self.hidden(xp)))[..., 0] + self.linear(x)[..., 0]
        context = torch.cat([mission, pooled], dim=1)
        home = self.home(context)
        logits = torch.cat([value.reshape(rows, -1), home], dim=1)
        logits = torch.where(allowed, logits, torch.full_like(logits, -torch.inf))
        return logits, self.critic(context)[:, 0]

    def to_net(self) -> OptionNet:
        """The policy part as numpy weights (M = 1)."""

        def a(t: torch.Tensor) -> np.ndarray:
            return t.detach().numpy().astype(float)

        return OptionNet(
            encoder_w=a(self.encoder.weight.T)[None],
            encoder_b=a(self.encoder.bias)[None],
            hidden_w=a(self.hidden.weight.T)[None],
            hidden_b=a(self.hidden.bias)[None],
            out_w=a(self.out.weight[0])[None],
            out_b=a(self.out.bias),
            linear_w=a(self.linear.weight[0])[None],
            home_w=a(self.home.weight[0])[None],
            home_b=a(self.home.bias),
        )


@dataclass
class Batch:
    """Decisions of one sensor count from one rollout."""

    features: list[tuple[np.ndarray, ...]] = field(default_factory=list)
    actions: list[np.ndarray] = field(default_factory=list)
    logp: list[np.ndarray] = field(default_factory=list)
    column: list[np.ndarray] = field(default_factory=list)
    slot: list[np.ndarray] = field(default_factory=list)


class Sampler:
    """The decision rule of a rollout: sample from the softmax, record the decision."""

    def __init__(self, model: TorchScorer, rng: np.random.Generator, slot: np.ndarray) -> None:
        self.model, self.rng, self.slot, self.batch = model, rng, slot, Batch()

    def __call__(self, decision: Decision) -> np.ndarray:
        features = option_features(decision)
        with torch.no_grad():
            logits, _ = self.model(*(torch.as_tensor(f) for f in features))
        logp = torch.log_softmax(logits, dim=1).numpy()
        # Gumbel-max: argmax(logp + Gumbel noise) is a draw from softmax (masked stay -inf)
        action = np.argmax(logp - np.log(-np.log(self.rng.random(logp.shape))), axis=1)
        b = self.batch
        b.features.append(features)
        b.actions.append(action)
        b.logp.append(logp[np.arange(len(action)), action])
        b.column.append(decision.rows.copy())
        b.slot.append(self.slot[decision.rows].copy())
        return action


def rollout(
    model: TorchScorer, missions: list[Any], reference: np.ndarray, rng: np.random.Generator
) -> tuple[dict[str, np.ndarray], float]:
    """Fly ``missions`` with sampled options; the decisions with their returns (relative to
    HGAD's total on each mission) and the mean relative gain of the batch."""
    engine = AutonomousEngine(missions, detail=False)
    sampler = Sampler(model, rng, engine.slot)
    runner = OptionRunner(engine.contexts(), sampler)
    t_max = int(engine.n_slots.max())
    bits = np.zeros((len(missions), t_max + 1))
    while not engine.done:
        observation = engine.observe()
        sampler.slot = observation.slot
        slots = observation.slot.copy()
        got = engine.step(runner.act(observation))
        live = observation.active
        bits[np.flatnonzero(live), slots[live]] = got[live]
    to_go = np.cumsum(bits[:, ::-1], axis=1)[:, ::-1]
    safe = np.where(reference > 0, reference, 1.0)
    b = sampler.batch
    column = np.concatenate(b.column)
    slot = np.concatenate(b.slot)
    out = {
        "sensor": np.concatenate([f[0] for f in b.features]),
        "option": np.concatenate([f[1] for f in b.features]),
        "mission": np.concatenate([f[2] for f in b.features]),
        "allowed": np.concatenate([f[3] for f in b.features]),
        "action": np.concatenate(b.actions),
        "logp": np.concatenate(b.logp),
        "return": to_go[column, slot] / safe[column],
    }
    gain = float(np.mean((bits.sum(axis=1) - reference) / safe))
    return out, gain


@dataclass
class PPOResult:
    """The trained model (the best validated one) and the run's figures."""

    net: OptionNet
    iterations: int
    missions_flown: int
    seconds: float
    curve: list[dict[str, float]]


def train_ppo(
    config: PPOConfig,
    seconds: float,
    validate: Callable[[OptionNet], dict[str, float]],
    validate_every: int = 5,
    max_iterations: int | None = None,
    log: Callable[[str], None] = print,
) -> PPOResult:
    """Train for ``seconds`` of wall time (or ``max_iterations``); as :func:`train_es`."""
    torch.manual_seed(config.seed)
    torch.set_num_threads(1)
    rng = np.random.default_rng(config.seed)
    start = time.monotonic()
    model = TorchScorer(initial_net(rng, config.hidden, config.width))
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate)
    pool = Pool(config.sensor_counts, _es_like(config))
    log(f"training missions built in {time.monotonic() - start:.0f} s")
    curve: list[dict[str, float]] = []
    best_score, best = -np.inf, model.to_net()
    iteration = flown = 0
    while time.monotonic() - start < seconds and (
        max_iterations is None or iteration < max_iterations
    ):
        counts = rng.choice(config.sensor_counts, config.counts_per_iteration, replace=False)
        batches, gains = [], []
        for n in counts:
            picks = rng.choice(config.pool_per_count, config.missions_per_batch, replace=False)
            missions = [pool.missions[int(n)][i] for i in picks]
            data, gain = rollout(model, missions, pool.hgad[int(n)][picks], rng)
            batches.append(data)
            gains.append(gain)
            flown += len(missions)
        _update(model, optimizer, batches, config, rng)
        iteration += 1
        if iteration % validate_every == 0:
            figures = validate(model.to_net())
            elapsed = time.monotonic() - start
            curve.append(
                {
                    "generation": float(iteration),
                    "seconds": elapsed,
                    "missions_flown": float(flown),
                    "train_fitness": float(np.mean(gains)),
                    **figures,
                }
            )
            if figures["score"] > best_score:
                best_score, best = figures["score"], model.to_net()
            log(
                f"iter {iteration:4d} {elapsed:6.0f} s  train {np.mean(gains):+.4f}  "
                + "  ".join(f"{k} {v:+.4f}" for k, v in figures.items())
            )
    if not curve:
        best = model.to_net()
    return PPOResult(best, iteration, flown, time.monotonic() - start, curve)


def _es_like(config: PPOConfig) -> Any:
    from learning.es import ESConfig

    return ESConfig(
        pool_per_count=config.pool_per_count,
        sensor_counts=config.sensor_counts,
        seed=config.seed,
        draw=config.draw,
    )


def _update(
    model: TorchScorer,
    optimizer: torch.optim.Optimizer,
    batches: list[dict[str, np.ndarray]],
    config: PPOConfig,
    rng: np.random.Generator,
) -> None:
    """PPO epochs over the decisions (minibatches within one sensor count)."""
    tensors = []
    for data in batches:
        t = {k: torch.as_tensor(v) for k, v in data.items()}
        with torch.no_grad():
            _, value = model(t["sensor"], t["option"], t["mission"], t["allowed"])
        advantage = t["return"] - value
        t["advantage"] = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
        tensors.append(t)
    for _ in range(config.epochs):
        for t in tensors:
            order = rng.permutation(len(t["action"]))
            for lo in range(0, len(order), config.minibatch):
                idx = torch.as_tensor(order[lo : lo + config.minibatch])
                logits, value = model(
                    t["sensor"][idx], t["option"][idx], t["mission"][idx], t["allowed"][idx]
                )
                logp_all = torch.log_softmax(logits, dim=1)
                logp = logp_all.gather(1, t["action"][idx][:, None])[:, 0]
                ratio = torch.exp(logp - t["logp"][idx])
                adv = t["advantage"][idx]
                surrogate = torch.min(
                    ratio * adv, torch.clamp(ratio, 1 - config.clip, 1 + config.clip) * adv
                )
                # masked options have logp -inf: keep them out of the product (a where over
                # the product would still send NaN gradients back through it)
                allowed = t["allowed"][idx]
                logp_safe = torch.where(allowed, logp_all, torch.zeros_like(logp_all))
                entropy = -(torch.exp(logp_safe) * logp_safe * allowed).sum(1)
                loss = (
                    -surrogate.mean()
                    + config.value_weight * ((value - t["return"][idx]) ** 2).mean()
                    - config.entropy_weight * entropy.mean()
                )
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(model.parameters(), 0.5)
                optimizer.step()
