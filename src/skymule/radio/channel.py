"""Compose a scenario's signal source: path-loss model, shadowing, fitted radio map; fading.

:func:`signal_source` returns the :class:`~skymule.radio.sources.SignalSource` a scenario's
``[radio]`` and ``[signal]`` sections describe for positions the UAV may take (model and
radio-map sources; recorded traces are replayed by :mod:`skymule.world` instead).
:func:`mission_fading_db` draws the per-slot small-scale fading of one mission.

Random draws come from generators seeded by the scenario's ``seed``, one independent stream
per purpose, so adding fading never changes the shadowing of a seed and vice versa.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from shapely.geometry import Polygon

from skymule.geo import LocalFrame
from skymule.radio.fading import draw_fading_db
from skymule.radio.shadowing import ShadowedSource, shadowing_field
from skymule.radio.sources import SignalSource, model_source
from skymule.scenario import Scenario

SHADOWING_STREAM = 1
"""Spawn key of the shadowing generator (SeedSequence(seed, spawn_key=(1,)))."""

FADING_STREAM = 2
"""Spawn key of the fading generator."""

REGION_PADDING_M = 500.0
"""The shadowing grid covers the sensors, the origin and the geofence plus this margin [m]."""


def stream_rng(seed: int, stream: int) -> np.random.Generator:
    """An independent generator for one purpose (``stream``) of a scenario ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(stream,)))


def region_xy_m(sensor_m: np.ndarray, fence: Polygon | None) -> np.ndarray:
    """(K, 2) corner points [m] of the area the UAV is expected to fly over (padded)."""
    points = [np.zeros((1, 2)), np.asarray(sensor_m, float)[:, :2]]
    if fence is not None:
        x0, y0, x1, y1 = fence.bounds
        points.append(np.array([[x0, y0], [x1, y1]]))
    xy = np.vstack(points)
    xy = xy[np.isfinite(xy).all(axis=1)]
    low, high = xy.min(axis=0) - REGION_PADDING_M, xy.max(axis=0) + REGION_PADDING_M
    return np.array([low, high])


def _model(scenario: Scenario, frame: LocalFrame, sensor_m: np.ndarray) -> SignalSource:
    return model_source(scenario.radio, sensor_m)


def _radiomap(scenario: Scenario, frame: LocalFrame, sensor_m: np.ndarray) -> SignalSource:
    from skymule.radio.radiomap import scenario_radiomap_source  # needs the trace readers

    return scenario_radiomap_source(scenario, frame, sensor_m)


SOURCE_BUILDERS: dict[str, Callable[[Scenario, LocalFrame, np.ndarray], SignalSource]] = {
    "model": _model,
    "radiomap": _radiomap,
}
"""``[signal] source`` name -> builder of a position-queryable signal source."""


def signal_source(
    scenario: Scenario, frame: LocalFrame, sensor_m: np.ndarray, fence: Polygon | None = None
) -> SignalSource:
    """The scenario's signal source, with shadowing when ``radio.shadowing_std_db > 0``.

    Shadowing applies to model sources only: a radio map already carries the measured
    spatial variation in its residual field.
    """
    source = SOURCE_BUILDERS[scenario.signal.source](scenario, frame, sensor_m)
    radio = scenario.radio
    if scenario.signal.source == "model" and radio.shadowing_std_db > 0:
        field = shadowing_field(
            stream_rng(scenario.seed, SHADOWING_STREAM),
            len(sensor_m),
            radio.shadowing_std_db,
            radio.shadowing_decorrelation_m,
            region_xy_m(sensor_m, fence),
        )
        source = ShadowedSource(source, field)
    return source


def mission_fading_db(scenario: Scenario, n_slots: int, n_sensors: int) -> np.ndarray | None:
    """(T, N) fading gains [dB] for one mission (None without fading), seeded by the scenario."""
    if scenario.radio.fading == "none":
        return None  # no Generator made (~0.1-0.5 ms) for nothing to draw
    rng = stream_rng(scenario.seed, FADING_STREAM)
    return draw_fading_db(scenario.radio, rng, n_slots, n_sensors)
