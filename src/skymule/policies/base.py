"""The policy contract: observations in, actions out, in two forms.

A **per-mission** policy (:class:`Policy`) sees one :class:`MissionContext` per mission
(``reset``) and one :class:`Observation` every slot (``act``) and returns an :class:`Action`.

A **batched** policy (:class:`BatchPolicy`, ``batched = True``) decides for B missions at
once: ``reset`` gets the B contexts, ``act`` a :class:`BatchObservation` whose arrays have a
leading mission axis, and it returns a :class:`BatchAction` of arrays. The engine runs B
missions as B columns either way; a per-mission policy runs through
:class:`~skymule.policies.batched.PerMission`, one instance per column.

Neither form touches engine state: buffers, position and the clock belong to the engine, and
every array a policy is handed is read-only.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

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

    @classmethod
    def of_rows(
        cls,
        slot: int,
        position_m: np.ndarray,
        snr_db: np.ndarray,
        rate_bps: np.ndarray,
        remaining_bit: np.ndarray,
    ) -> Observation:
        """An observation of rows of read-only batch arrays, which are views that cannot be
        made writeable (the engine's own fast path: no further views are taken)."""
        observation = object.__new__(cls)
        observation.__dict__.update(
            slot=slot,
            position_m=position_m,
            snr_db=snr_db,
            rate_bps=rate_bps,
            remaining_bit=remaining_bit,
        )
        return observation


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

    The engine hands policies fresh arrays it does not read again, or views of read-only
    bases (whose views cannot be made writeable), so a policy cannot reach engine state.
    """
    view = np.asarray(values).view()
    view.flags.writeable = False
    return view


def stacked(contexts: Sequence[MissionContext], field: str) -> np.ndarray:
    """(B, ...) one field of every mission's context, stacked over the mission axis (the
    engine's own array where it holds one: no context is made per mission)."""
    stack = getattr(contexts, "stack", None)
    found = stack(field) if stack is not None else None
    if found is not None:
        return found
    return read_only(np.array([getattr(context, field) for context in contexts]))


class Policy(Protocol):
    """A per-mission decision maker. Create a fresh one (or ``reset``) for every mission."""

    name: str

    def reset(self, context: MissionContext) -> None:
        """Start a mission: ``context`` is all the policy may know before it (read-only)."""
        ...

    def act(self, observation: Observation) -> Action:
        """Decide slot ``observation.slot``: whom to serve, whether to hover, where to fly."""
        ...


@dataclass(frozen=True)
class BatchObservation:
    """What the UAVs of B missions know at the start of their current slots (read-only).

    Row b is mission b (the order of the contexts given to ``reset``). Missions that are over
    (``active`` False) keep their last values; what a policy returns for them is ignored.

    Attributes:
        slot: (B,) slot index t of each mission.
        active: (B,) True where the mission is still running.
        position_m: (B, 3) UAV positions r_t [m].
        snr_db: (B, N) SNR to each sensor [dB] (-inf where there is no link).
        rate_bps: (B, N) rate to each sensor [bit/s].
        remaining_bit: (B, N) data left in each buffer at the start of the slot [bit].
    """

    slot: np.ndarray
    active: np.ndarray
    position_m: np.ndarray
    snr_db: np.ndarray
    rate_bps: np.ndarray
    remaining_bit: np.ndarray

    @property
    def size(self) -> int:
        """B, the number of missions."""
        return int(self.slot.shape[0])

    def missions(self) -> tuple[Observation, ...]:
        """Every row as a per-mission :class:`Observation`."""
        return tuple(self.mission(b) for b in range(self.size))

    def mission(self, b: int) -> Observation:
        """Row b as a per-mission :class:`Observation` (read-only views, no copies)."""
        return Observation.of_rows(
            int(self.slot[b]),
            self.position_m[b],
            self.snr_db[b],
            self.rate_bps[b],
            self.remaining_bit[b],
        )


@dataclass(frozen=True)
class BatchAction:
    """What the UAVs of B missions do this slot (each field an array over missions).

    Attributes:
        serve: (B,) int sensor to download from, -1 (``NO_SENSOR``) for none.
        hover: (B,) bool, True to stay where it is after this slot (fixed trajectories: do not
            advance), or None: never.
        goto_m: (B, 2) autonomous: point (x, y) [m] to fly toward, NaN to stay; None: stay.
        target: (B,) autonomous: the sensor whose hover point the UAV heads for (logged;
            defines the visit order), -1 for none; None: none.
    """

    serve: np.ndarray
    hover: np.ndarray | None = None
    goto_m: np.ndarray | None = None
    target: np.ndarray | None = None


class BatchPolicy(Protocol):
    """A decision maker for B missions at once (``batched = True``).

    ``reset`` starts B missions; ``act`` decides one slot of each. Keep per-mission state in
    arrays with a leading mission axis; a single run is a batch of one.
    """

    name: str
    batched: bool

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        """Start B missions: ``contexts[b]`` is what mission b's policy may know (read-only)."""
        ...

    def act(self, observation: BatchObservation) -> BatchAction:
        """Decide the current slot of every mission (rows of ``observation``)."""
        ...
