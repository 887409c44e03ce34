"""The policy contract: observations in, actions out.

A policy sees a :class:`MissionContext` once per mission (``reset``) and an
:class:`Observation` every slot (``act``) and returns an :class:`Action`. It never touches
engine state: buffers, position and the clock belong to the engine.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from skymule.sim.contract import served_bits

if TYPE_CHECKING:
    from skymule.flight.navigation import Navigator


@dataclass(frozen=True)
class MissionContext:
    """What a policy may know before the mission starts.

    Attributes:
        sensor_names: the N sensor names, in index order.
        slot_s: slot length [s].
        n_slots: number of slots T.
        buffers_bit: (N,) initial buffers [bit].
        peak_rate_bps: (N,) largest rate each sensor reaches over the historical data (the
            whole recorded trace, or the nominal path sampled at slot_s) [bit/s].
        mode: "fixed" or "autonomous".
        sensor_m: (N, 3) sensor antenna positions [m] (NaN where unknown).
        hover_points_m: autonomous: (N, 2) point inside the geofence closest to each sensor,
            where the UAV serves it from [m] (NaN where unknown); None on fixed paths.
        home_m: autonomous: (2,) home point [m]; None on fixed paths.
        max_step_m: autonomous: longest move in one slot, max_speed_mps * slot_s [m].
        visit_radius_m: autonomous: a sensor counts as visited within this distance of its
            hover point [m].
        navigator: autonomous: in-fence shortest paths (read-only use: ``travel_distance``,
            ``shortest_path``); None on fixed paths.
        predict_snr_db: autonomous: the model's SNR at any positions, (P, 3) [m] -> (P, N)
            [dB], without per-slot fading (what a planner may predict from); None if unknown.
        return_home: autonomous: whether the UAV must be home when the mission ends.
        rate_of_snr_bps: autonomous: the rate table x bandwidth, SNR [dB] (any shape) ->
            rate [bit/s]; None if unknown.
        track_rate_bps: fixed paths: (K, N) rate at every track sample [bit/s], the whole
            signal ahead of time for offline planners (``optimal-fixed``); None otherwise.
        track_hold_at_end: fixed paths: True for a planned path (hold at the end), False for
            a recorded trace (the mission ends after the last sample).
    """

    sensor_names: tuple[str, ...]
    slot_s: float
    n_slots: int
    buffers_bit: np.ndarray
    peak_rate_bps: np.ndarray
    mode: str
    sensor_m: np.ndarray
    hover_points_m: np.ndarray | None = None
    home_m: np.ndarray | None = None
    max_step_m: float = 0.0
    visit_radius_m: float = 50.0
    navigator: Navigator | None = None
    predict_snr_db: Callable[[np.ndarray], np.ndarray] | None = None
    return_home: bool = True
    rate_of_snr_bps: Callable[[np.ndarray], np.ndarray] | None = None
    track_rate_bps: np.ndarray | None = None
    track_hold_at_end: bool = True

    def __post_init__(self) -> None:
        for name in (
            "buffers_bit",
            "peak_rate_bps",
            "sensor_m",
            "hover_points_m",
            "home_m",
            "track_rate_bps",
        ):
            values = getattr(self, name)
            if values is not None:
                object.__setattr__(self, name, read_only(values))


@dataclass(frozen=True)
class Observation:
    """What the UAV knows at the start of slot ``slot`` (read-only: writing raises).

    Attributes:
        slot: slot index t.
        position_m: (3,) UAV position r_t [m].
        snr_db: (N,) SNR to each sensor at r_t [dB] (-inf where there is no link).
        rate_bps: (N,) rate to each sensor at r_t [bit/s].
        remaining_bit: (N,) data left in each buffer at the start of the slot [bit].
    """

    slot: int
    position_m: np.ndarray
    snr_db: np.ndarray
    rate_bps: np.ndarray
    remaining_bit: np.ndarray

    def __post_init__(self) -> None:
        for name in ("position_m", "snr_db", "rate_bps", "remaining_bit"):
            object.__setattr__(self, name, read_only(getattr(self, name)))


@dataclass(frozen=True)
class Action:
    """What the UAV does in a slot.

    Attributes:
        serve: index of the sensor to download from, or None.
        hover: True to stay where it is after this slot (fixed trajectories: do not advance).
        goto_m: autonomous trajectories: the point (x, y) [m] to fly toward, or None to stay.
        target: autonomous trajectories: the sensor whose hover point the UAV is heading for
            or hovering at (logged; defines the visit order), or None.
    """

    serve: int | None
    hover: bool = False
    goto_m: tuple[float, float] | None = None
    target: int | None = None


def read_only(values: np.ndarray) -> np.ndarray:
    """A view of ``values`` that raises on writing (the engine's arrays stay the engine's).

    The engines hand policies read-only base arrays or fresh copies, so a policy cannot turn
    writing back on and reach engine state through the view.
    """
    view = np.asarray(values).view()
    view.flags.writeable = False
    return view


class Policy(Protocol):
    """A per-mission decision maker. Create a fresh one (or ``reset``) for every mission."""

    name: str

    def reset(self, context: MissionContext) -> None: ...

    def act(self, observation: Observation) -> Action: ...


def slot_download_bit(observation: Observation, sensor: int, slot_s: float) -> float:
    """Bits sensor ``sensor`` would deliver this slot: min(R * dt, Q) (the slot contract)."""
    return float(
        served_bits(observation.rate_bps[sensor], observation.remaining_bit[sensor], slot_s)
    )
