"""Distributions a sweep axis may draw from (``dist = NAME``): parameters, checks and draws.

Every draw comes from the numpy Generator the sweep hands in (seeded per combination).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Distribution:
    """A named distribution with validated parameters (``draw(rng, size) -> (size,)``)."""

    name: str
    params: tuple[tuple[str, Any], ...]

    def draw(self, rng: np.random.Generator, size: int) -> list[Any]:
        return DISTRIBUTIONS[self.name].draw(rng, self._params, size)

    @functools.cached_property
    def _params(self) -> dict[str, Any]:  # a sweep draws once per mission: made once
        return dict(self.params)


@dataclass(frozen=True)
class DistributionKind:
    """Parameters a distribution takes, their check, and how to draw from it."""

    params: tuple[str, ...]
    check: Callable[[dict[str, Any]], str | None]
    draw: Callable[[np.random.Generator, dict[str, Any], int], list[Any]]


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _numbers(params: dict[str, Any]) -> str | None:
    bad = [k for k, v in params.items() if not _is_number(v)]
    return f"{bad[0]} = {params[bad[0]]!r} must be a finite number" if bad else None


def _check_low_high(params: dict[str, Any]) -> str | None:
    problem = _numbers(params)
    if problem is None and not params["low"] < params["high"]:
        return f"low = {params['low']!r} must be below high = {params['high']!r}"
    return problem


def _check_spread(name: str) -> Callable[[dict[str, Any]], str | None]:
    def check(params: dict[str, Any]) -> str | None:
        problem = _numbers(params)
        if problem is None and params[name] < 0:
            return f"{name} = {params[name]!r} must be >= 0"
        return problem

    return check


def _check_integers(params: dict[str, Any]) -> str | None:
    problem = _check_low_high(params)
    if problem is None and not all(isinstance(params[k], int) for k in ("low", "high")):
        return "low and high must be integers"
    return problem


def _check_choice(params: dict[str, Any]) -> str | None:
    values = params["values"]
    return None if isinstance(values, list) and values else "values must be a non-empty list"


DISTRIBUTIONS: dict[str, DistributionKind] = {
    "uniform": DistributionKind(
        ("low", "high"),
        _check_low_high,
        lambda rng, p, n: rng.uniform(p["low"], p["high"], n).tolist(),
    ),
    "normal": DistributionKind(
        ("mean", "std"),
        _check_spread("std"),
        lambda rng, p, n: rng.normal(p["mean"], p["std"], n).tolist(),
    ),
    "lognormal": DistributionKind(
        ("mean", "sigma"),
        _check_spread("sigma"),
        lambda rng, p, n: rng.lognormal(p["mean"], p["sigma"], n).tolist(),
    ),
    "integers": DistributionKind(
        ("low", "high"),
        _check_integers,
        lambda rng, p, n: rng.integers(p["low"], p["high"], n).tolist(),
    ),
    "choice": DistributionKind(
        ("values",),
        _check_choice,
        lambda rng, p, n: [p["values"][i] for i in rng.integers(0, len(p["values"]), n)],
    ),
}
"""Distribution registry: ``dist = NAME`` -> parameters, check and draw."""
