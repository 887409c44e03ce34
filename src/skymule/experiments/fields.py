"""Scenario dictionaries edited along dotted field paths (what a sweep axis names).

``("sensors", "*", "buffer_mbit")`` sets every sensor's buffer; only the dictionaries and lists
on the path are copied, so thousands of missions share the rest of the base scenario.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.geo import LocalFrame
from skymule.scenario import Scenario

Path_ = tuple[str | int, ...]
"""A parsed axis key: field names, list indices and "*" (every element)."""


def _fail(source: str, message: str) -> SkymuleError:
    return SkymuleError(f"{source}: {message}")


def assign(node: Any, path: Path_, value: Any, source: str, key: str) -> Any:
    """A copy of ``node`` with ``path`` set to ``value`` (lists for "*"); copies only the path."""
    head, rest = path[0], path[1:]
    if head == "*" or isinstance(head, int):
        if not isinstance(node, list):
            raise _fail(source, f"axes.{key}: {head!r} indexes a field that is not a list")
        items = list(node)
        if isinstance(head, int):
            if head >= len(items):
                raise _fail(
                    source, f"axes.{key}: index {head} out of range; the base has {len(items)}"
                )
            targets: Sequence[int] = [head]
        else:
            targets = range(len(items))
        for i in targets:
            item = value[i] if head == "*" else value
            items[i] = assign(items[i], rest, item, source, key) if rest else item
        return items
    if not isinstance(node, dict):
        raise _fail(source, f"axes.{key}: {head!r} is not a field of a table")
    copy = dict(node)
    if rest:
        copy[head] = assign(copy.get(head, {}), rest, value, source, key)
    else:
        copy[head] = value
    return copy


def stars(path: Path_, base: dict[str, Any]) -> int | None:
    """Number of elements a "*" in ``path`` spans in ``base`` (None without a "*")."""
    node: Any = base
    for part in path:
        if part == "*":
            return len(node) if isinstance(node, list) else 0
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and isinstance(part, int) and part < len(node):
            node = node[part]
        else:
            node = None
    return None


def base_dict(base: Scenario) -> dict[str, Any]:
    """The base scenario as a dict, with lat/lon sensors also placed in local metres."""
    data = base.to_toml_dict()
    frame = LocalFrame(base.site.origin.lat, base.site.origin.lon)
    sensors = []
    for sensor in data["sensors"]:
        if "lat" in sensor and "x_m" not in sensor:
            x_m, y_m = frame.to_local(sensor["lat"], sensor["lon"])
            sensor = {**sensor, "_xy": (float(x_m), float(y_m))}
        sensors.append(sensor)
    return {**data, "sensors": sensors}


def place_sensors(data: dict[str, Any]) -> dict[str, Any]:
    """Sensors given x_m or y_m by an axis drop lat/lon (converted to metres)."""
    sensors = []
    for sensor in data.get("sensors", []):
        if isinstance(sensor, dict) and "_xy" in sensor:
            sensor = dict(sensor)
            x_m, y_m = sensor.pop("_xy")
            if "x_m" in sensor or "y_m" in sensor:
                sensor.pop("lat", None)
                sensor.pop("lon", None)
                sensor.setdefault("x_m", x_m)
                sensor.setdefault("y_m", y_m)
        sensors.append(sensor)
    return {**data, "sensors": sensors}


def canonical(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)


def draw_hash(key: Any) -> int:
    """The 64-bit number a combination ``key`` adds to the sweep seed (:func:`draw_seed`)."""
    return int.from_bytes(hashlib.sha256(canonical(key).encode()).digest()[:8], "little")


def draw_seed(seed: int, key: Any) -> np.random.Generator:
    return np.random.default_rng([seed, draw_hash(key)])


def column(key: str, index: int) -> str:
    return key.replace("[*]", f"[{index}]", 1)
