"""The values of a radio map read from a file, checked before any of them is used.

A map file is shared like a trace: a NaN exponent, an infinite antenna position or an
intercept of 1e308 dB parse as JSON numbers, and unchecked they give ``sim2real`` a null RMSE
and ``run`` a tower that serves nothing, both with exit status 0. :func:`map_problem` names
the first value that is not a number a fitted map can hold, in one line.

The bounds are generous on purpose (a fit extrapolates its trend to 1 m, and kriging weights
of close samples are large); they only exclude values no fit produces and whose arithmetic
overflows.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from skymule.limits import MAX_COORDINATE_M

MAX_INTERCEPT_DB = 1000.0
"""Largest |A|, the trend's SNR at 1 m [dB] (10^100 in power: no link is near it)."""

MAX_EXPONENT = 20.0
"""Largest |n|, the path-loss exponent (200 dB a decade of distance; free space is 2)."""

MAX_VARIANCE_DB2 = 1e6
"""Largest sill or nugget [dB^2] (a standard deviation of 1000 dB)."""

MAX_WEIGHT_DB = 1e12
"""Largest |kriging weight| [dB] (products with the sill and sums over samples stay finite)."""


def _numbers(value: Any) -> Iterator[float]:
    """Every number in a nested list/dict (what a map's ``to_dict`` holds)."""
    if isinstance(value, dict):
        for item in value.values():
            yield from _numbers(item)
    elif isinstance(value, list | tuple):
        for item in value:
            yield from _numbers(item)
    elif isinstance(value, int | float) and not isinstance(value, bool):
        yield float(value)


def _outside(values: np.ndarray, low: float, high: float) -> float | None:
    """The first value not finite or outside [low, high], or None."""
    flat = np.asarray(values, float).ravel()
    bad = ~np.isfinite(flat) | (flat < low) | (flat > high)
    return float(flat[int(np.argmax(bad))]) if bad.any() else None


def _sensor_problem(where: str, sensor: Any) -> str | None:
    """What is wrong with one ``SensorMap``'s values, or None."""
    checks: list[tuple[str, Any, float, float, str]] = [
        ("position_m", sensor.position_m, -MAX_COORDINATE_M, MAX_COORDINATE_M, "m"),
        ("intercept_db", sensor.intercept_db, -MAX_INTERCEPT_DB, MAX_INTERCEPT_DB, "dB"),
        ("exponent", sensor.exponent, -MAX_EXPONENT, MAX_EXPONENT, ""),
        ("sill_db2", sensor.variogram.sill_db2, 0.0, MAX_VARIANCE_DB2, "dB^2"),
        ("nugget_db2", sensor.variogram.nugget_db2, 0.0, MAX_VARIANCE_DB2, "dB^2"),
        ("train_m", sensor.train_m, -MAX_COORDINATE_M, MAX_COORDINATE_M, "m"),
        ("weights", sensor.weights, -MAX_WEIGHT_DB, MAX_WEIGHT_DB, "dB"),
    ]
    for name, value, low, high, unit in checks:
        bad = _outside(value, low, high)
        if bad is not None:
            return f"{where}.{name} = {bad!r}: allowed: finite, {low:g} to {high:g} {unit}".rstrip()
    range_m = float(sensor.variogram.range_m)
    if not (math.isfinite(range_m) and 0 < range_m <= MAX_COORDINATE_M):
        return f"{where}.range_m = {range_m!r}: allowed: above 0, at most {MAX_COORDINATE_M:g} m"
    if np.shape(sensor.position_m) != (3,):
        return f"{where}.position_m has shape {np.shape(sensor.position_m)}; expected (3,)"
    if sensor.weights.shape != (sensor.train_m.shape[0],):
        return (
            f"{where}.weights has {sensor.weights.size} values for {sensor.train_m.shape[0]} "
            "train_m points; expected one weight a point"
        )
    if sensor.ensemble is not None:
        numbers = _numbers(sensor.ensemble.to_dict())
        bad_net = next((v for v in numbers if not math.isfinite(v)), None)
        if bad_net is not None:
            return f"{where}.ensemble holds {bad_net!r}; allowed: finite numbers"
    return None


def map_problem(radio_map: Any, where: str = "") -> str | None:
    """What is wrong with the values of a :class:`~skymule.radio.radiomap.RadioMap` read
    from a file (its prior's too), or None. ``where`` prefixes the field names."""
    lat, lon = radio_map.origin
    if not (math.isfinite(lat) and abs(lat) <= 90 and math.isfinite(lon) and abs(lon) <= 180):
        return f"{where}origin = ({lat!r}, {lon!r}): allowed: lat -90 to 90, lon -180 to 180"
    for index, sensor in enumerate(radio_map.sensors):
        if not isinstance(sensor.name, str) or not sensor.name.strip():
            return f"{where}sensors[{index}].name = {sensor.name!r}: allowed: a sensor name"
        problem = _sensor_problem(f"{where}sensors[{index}] ({sensor.name})", sensor)
        if problem:
            return problem
    prior = radio_map.prior
    if prior is None:
        return None
    if hasattr(prior, "fitted"):  # a MapPrior: a map of its own, and the frame offset
        bad = _outside(prior.offset_m, -MAX_COORDINATE_M, MAX_COORDINATE_M)
        if bad is not None:
            return f"{where}prior.offset_m holds {bad!r}: allowed: finite, at most 1e+07 m"
        return map_problem(prior.fitted, f"{where}prior.map.")
    for name, position in prior.sensor_m.items():  # a ModelPrior: sensor positions, [radio]
        bad = _outside(np.asarray(position), -MAX_COORDINATE_M, MAX_COORDINATE_M)
        if bad is not None:
            return f"{where}prior.sensor_m.{name} holds {bad!r}: allowed: finite, within 1e+07 m"
    from pydantic import ValidationError

    from skymule.scenario import RadioSpec

    try:
        RadioSpec.model_validate({**prior.radio, "shadowing_std_db": 0.0})
    except ValidationError as exc:
        error = exc.errors()[0]
        field = ".".join(str(p) for p in error["loc"])
        return f"{where}prior.radio.{field} = {error.get('input')!r}: {error['msg']}"
    return None
