"""Policies as the engine runs them: one batched policy for the B columns of a batch.

* :class:`PerMission` runs per-mission policies (:class:`~skymule.policies.base.Policy`), one
  instance per column, behind the batched interface: each slot it hands every running
  mission its row of the :class:`~skymule.policies.base.BatchObservation` (read-only views)
  and gathers the actions into arrays.
* :class:`Columns` runs several batched policies side by side, each on its own columns (a
  sweep whose missions differ in policy).
* :func:`batch_policy` makes the policy of a batch from each mission's ``[policy]`` section.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.policies.base import (
    Action,
    BatchAction,
    BatchObservation,
    BatchPolicy,
    MissionContext,
    Observation,
    Policy,
)
from skymule.rules.contract import NO_SENSOR


def check_serve(serve: int | None, n_sensors: int, who: str) -> int:
    """The served sensor index of an action (NO_SENSOR for None); SkymuleError if invalid."""
    if serve is None:
        return NO_SENSOR
    if type(serve) is int and 0 <= serve < n_sensors:
        return serve
    if isinstance(serve, bool) or not isinstance(serve, int | np.integer):
        raise SkymuleError(
            f"policy {who!r} chose sensor {serve!r}; allowed: 0..{n_sensors - 1} or None"
        )
    if not 0 <= int(serve) < n_sensors:
        raise SkymuleError(
            f"policy {who!r} chose sensor {serve}; allowed: 0..{n_sensors - 1} or None"
        )
    return int(serve)


def check_goto(goto_m: Any, who: str) -> tuple[float, float]:
    """An action's ``goto_m`` as two finite floats; SkymuleError naming the value if not."""
    try:
        x_m, y_m = (float(v) for v in goto_m)
    except (TypeError, ValueError):
        x_m = y_m = math.nan
    if not (math.isfinite(x_m) and math.isfinite(y_m)):
        raise SkymuleError(
            f"policy {who!r} returned goto_m = {goto_m!r}; allowed: (x_m, y_m), two finite "
            "numbers, or None to stay"
        )
    return x_m, y_m


def joined_name(names: Sequence[str]) -> str:
    """One name for several policies: the name itself when they agree, else 'a+b'."""
    distinct = sorted(set(names))
    return distinct[0] if len(distinct) == 1 else "+".join(distinct)


class PerMission:
    """Per-mission policies, one per column, as one batched policy.

    Args:
        policies: one fresh per-mission policy per column.
        labels: how errors name each column's policy (default: its name).
    """

    batched = True

    def __init__(self, policies: Sequence[Policy], labels: Sequence[str] | None = None) -> None:
        self.policies = tuple(policies)
        self.name = joined_name([p.name for p in self.policies])
        self._labels = tuple(p.name for p in self.policies) if labels is None else tuple(labels)
        self._n_sensors = 0

    def names(self) -> tuple[str, ...]:
        """(B,) each column's policy name."""
        return tuple(p.name for p in self.policies)

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        if len(contexts) != len(self.policies):
            raise ValueError(f"{len(contexts)} contexts for {len(self.policies)} policies")
        for policy, context in zip(self.policies, contexts, strict=True):
            policy.reset(context)
        self._n_sensors = len(contexts[0].sensor_names) if contexts else 0

    def act(self, observation: BatchObservation) -> BatchAction:
        size = observation.size
        serve = np.full(size, NO_SENSOR, np.int64)
        hover = np.zeros(size, bool)
        goto = np.full((size, 2), np.nan)
        target = np.full(size, NO_SENSOR, np.int64)
        active = observation.active
        rows = range(size) if active.all() else np.flatnonzero(active).tolist()
        slot, position = observation.slot, observation.position_m
        snr, rate, remaining = observation.snr_db, observation.rate_bps, observation.remaining_bit
        for b in rows:
            policy = self.policies[b]
            action: Action = policy.act(
                Observation.of_rows(int(slot[b]), position[b], snr[b], rate[b], remaining[b])
            )
            serve[b] = check_serve(action.serve, self._n_sensors, self._labels[b])
            if action.hover:
                hover[b] = True
            if action.goto_m is not None:
                goto[b] = check_goto(action.goto_m, self._labels[b])
            if action.target is not None:
                target[b] = action.target
        return BatchAction(serve=serve, hover=hover, goto_m=goto, target=target)


def _sub_observation(observation: BatchObservation, cols: np.ndarray) -> BatchObservation:
    """Rows ``cols`` of ``observation`` (copies, read-only)."""
    parts = []
    for values in (
        observation.slot,
        observation.active,
        observation.position_m,
        observation.snr_db,
        observation.rate_bps,
        observation.remaining_bit,
    ):
        part = values[cols]
        part.flags.writeable = False
        parts.append(part.view())
    return BatchObservation(*parts)


class Columns:
    """Batched policies side by side, each deciding for its own columns of the batch.

    Args:
        parts: (policy, columns) pairs; every column belongs to exactly one part.
    """

    batched = True

    def __init__(self, parts: Sequence[tuple[BatchPolicy, np.ndarray]]) -> None:
        self.parts = [(policy, np.asarray(cols, np.int64)) for policy, cols in parts]
        self.size = sum(cols.size for _, cols in self.parts)
        covered = np.sort(np.concatenate([cols for _, cols in self.parts]))
        if not np.array_equal(covered, np.arange(self.size)):
            raise ValueError("Columns: every column must belong to exactly one part")
        self.name = joined_name([policy.name for policy, _ in self.parts])

    def names(self) -> tuple[str, ...]:
        """(B,) each column's policy name."""
        out = [""] * self.size
        for policy, cols in self.parts:
            for col, name in zip(cols.tolist(), policy_names(policy, cols.size), strict=True):
                out[col] = name
        return tuple(out)

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        for policy, cols in self.parts:
            policy.reset([contexts[c] for c in cols.tolist()])

    def slot_rule(self) -> Any:
        """The parts' compiled rules merged column by column, or None if some part has none."""
        from skymule.policies.builtin import SlotRule

        found = [getattr(policy, "slot_rule", lambda: None)() for policy, _ in self.parts]
        rules: list[SlotRule] = [rule for rule in found if rule is not None]
        if len(rules) < len(found):
            return None
        n_sensors = max(rule.threshold_bps.shape[1] for rule in rules)
        merged = SlotRule(
            np.zeros(self.size, bool),
            np.zeros((self.size, n_sensors)),
            np.zeros((self.size, n_sensors)),
            np.zeros(self.size),
        )
        for rule, (_, cols) in zip(rules, self.parts, strict=True):
            merged.hgad[cols] = rule.hgad
            merged.threshold_bps[cols] = rule.threshold_bps
            merged.peak_rate_bps[cols] = rule.peak_rate_bps
            merged.max_hover_s[cols] = rule.max_hover_s
        return merged

    def act(self, observation: BatchObservation) -> BatchAction:
        size = observation.size
        serve = np.full(size, NO_SENSOR, np.int64)
        hover = np.zeros(size, bool)
        goto = np.full((size, 2), np.nan)
        target = np.full(size, NO_SENSOR, np.int64)
        for policy, cols in self.parts:
            action = policy.act(_sub_observation(observation, cols))
            serve[cols] = action.serve
            if action.hover is not None:
                hover[cols] = action.hover
            if action.goto_m is not None:
                goto[cols] = action.goto_m
            if action.target is not None:
                target[cols] = action.target
        return BatchAction(serve=serve, hover=hover, goto_m=goto, target=target)


def policy_names(policy: BatchPolicy, size: int) -> tuple[str, ...]:
    """(B,) the name logged for each column of ``policy``."""
    names: Callable[[], tuple[str, ...]] | None = getattr(policy, "names", None)
    return names() if names is not None else (policy.name,) * size


def is_batched(policy: object) -> bool:
    """True if ``policy`` declares the batched interface (``batched = True``)."""
    return getattr(policy, "batched", False) is True


def as_batch_policy(policies: Policy | BatchPolicy | Sequence[Policy]) -> BatchPolicy:
    """A batched policy from a batched one (as it is), a per-mission one (a batch of one) or
    one per-mission policy per column."""
    if isinstance(policies, Sequence):
        return PerMission(policies)
    if is_batched(policies):
        batched: BatchPolicy = policies  # type: ignore[assignment]
        return batched
    single: Policy = policies  # type: ignore[assignment]
    return PerMission([single])


class PerFleet:
    """Fleet policies (one decision for all K UAVs of a fleet mission, e.g. ``coordinated``)
    as one batched policy over fleet columns: column c is UAV c % K of fleet mission c // K.

    Args:
        policies: one fresh fleet policy per fleet mission.
        uavs: K, the UAVs of each fleet mission.
    """

    batched = True

    def __init__(self, policies: Sequence[Any], uavs: int) -> None:
        self.policies = tuple(policies)
        self.uavs = uavs
        self.name = joined_name([p.name for p in self.policies])
        self._n_sensors = 0

    def names(self) -> tuple[str, ...]:
        """(B,) each column's policy name."""
        return tuple(name for policy in self.policies for name in policy.names())

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        k = self.uavs
        if len(contexts) != k * len(self.policies):
            raise ValueError(f"{len(contexts)} contexts for {len(self.policies)} fleets of {k}")
        for m, policy in enumerate(self.policies):
            policy.reset(list(contexts[m * k : (m + 1) * k]))
        self._n_sensors = len(contexts[0].sensor_names) if contexts else 0

    def act(self, observation: BatchObservation) -> BatchAction:
        size, k = observation.size, self.uavs
        serve = np.full(size, NO_SENSOR, np.int64)
        hover = np.zeros(size, bool)
        goto = np.full((size, 2), np.nan)
        target = np.full(size, NO_SENSOR, np.int64)
        for m, policy in enumerate(self.policies):
            columns = range(m * k, (m + 1) * k)
            if not observation.active[m * k]:
                continue
            actions = policy.act(tuple(observation.mission(c) for c in columns))
            names = policy.names()
            for c, action, name in zip(columns, actions, names, strict=True):
                who = f"{name} (UAV {c - m * k})"
                serve[c] = check_serve(action.serve, self._n_sensors, who)
                hover[c] = bool(action.hover)
                if action.goto_m is not None:
                    goto[c] = check_goto(action.goto_m, who)
                if action.target is not None:
                    target[c] = action.target
        return BatchAction(serve=serve, hover=hover, goto_m=goto, target=target)
