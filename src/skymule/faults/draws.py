"""One mission's faults, drawn once: per-slot masks and errors every engine applies the same way.

:func:`draw_faults` turns a scenario's ``[[faults]]`` entries into a frozen :class:`FaultDraws`
of per-slot arrays. Draw it once per mission and hand the same object to every policy
(paired comparisons: each policy meets the same outages). :func:`stack_draws` puts several
missions' draws on a leading missions axis for a batched engine. How engines apply the
arrays is the contract in ``docs/faults.md`` (:meth:`FaultDraws.deliverable` here, what a
policy sees in :func:`skymule.sim.batch_faults.apply_faults`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from typing import Any, Protocol

import numpy as np

from skymule.faults.models import (
    ar1_normal,
    correlation_per_slot,
    gilbert_elliott_loss,
    outage_windows,
)
from skymule.faults.motion import J_PER_WH, Battery, Wind
from skymule.faults.specs import (
    BatteryParams,
    FaultParams,
    GilbertElliottParams,
    GpsErrorParams,
    MissedPollParams,
    OutageParams,
    SnrErrorParams,
    WindParams,
    fault_params,
)

FAULT_STREAM = 3
"""Spawn key of the fault generator: SeedSequence(seed, spawn_key=(3,)). Shadowing (1) and
fading (2) use their own streams, so turning faults on changes no other draw."""


UAV_FAULT_STREAM = 5
"""Spawn key of the per-UAV fault generators of a fleet's UAVs after the first:
SeedSequence(seed, spawn_key=(5, uav)) (4 is taken by the resilience study's buffers)."""

TOWER_FIELDS = ("outage", "burst_loss")
"""Draws that belong to the towers (an outage, a link's Gilbert-Elliott state): every UAV of
a fleet meets the same ones. The other per-slot draws (SNR error, missed polls, GPS error)
belong to each UAV's own radio and receiver."""


def fault_rng(seed: int) -> np.random.Generator:
    """The generator a mission's faults are drawn from, for scenario ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(FAULT_STREAM,)))


def uav_fault_rng(seed: int, uav: int) -> np.random.Generator:
    """The generator of UAV ``uav``'s own faults in a fleet: UAV 0's is :func:`fault_rng`
    (so a fleet of one is the single-UAV mission), the others' their own streams."""
    if uav == 0:
        return fault_rng(seed)
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(UAV_FAULT_STREAM, uav)))


class FaultEntry(Protocol):
    """A ``[[faults]]`` entry: :class:`skymule.scenario.FaultSpec` or anything alike."""

    @property
    def kind(self) -> str: ...

    @property
    def params(self) -> dict[str, Any]: ...


@dataclass(frozen=True)
class FaultDraws:
    """Per-slot faults of one mission; shapes below, with a leading missions axis M if stacked.

    Attributes:
        outage: (T, N) True where a tower outage window covers slot t of sensor i.
        burst_loss: (T, N) True where the Gilbert-Elliott link of sensor i loses slot t.
        snr_error_db: (T, N) error [dB] added to the SNR the policy sees (0: exact).
        poll_missed: (T,) True where the slot's poll is missed: nothing is served.
        gps_error_m: (T, 2) error (east, north) [m] on the position the policy sees.
        wind: steady wind, or None.
        battery: battery limit, or None.
    """

    outage: np.ndarray
    burst_loss: np.ndarray
    snr_error_db: np.ndarray
    poll_missed: np.ndarray
    gps_error_m: np.ndarray
    wind: Wind | None = None
    battery: Battery | None = None

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    @property
    def link_up(self) -> np.ndarray:
        """(T, N) True where sensor i's link works in slot t (no outage, no burst loss)."""
        return ~(self.outage | self.burst_loss)

    def deliverable(self) -> np.ndarray:
        """(T, N) True where a served sensor delivers data: its link is up and the poll is not
        missed. Elsewhere a served sensor delivers 0 bits."""
        return self.link_up & ~self.poll_missed[..., None]

    @property
    def affected(self) -> np.ndarray:
        """(T,) True for slots touched by a per-slot fault (for the mission log)."""
        per_sensor = ~self.link_up | (self.snr_error_db != 0)
        return self.poll_missed | per_sensor.any(axis=-1) | (self.gps_error_m != 0).any(axis=-1)

    @property
    def is_empty(self) -> bool:
        """True when nothing is faulty: an engine may skip every fault step."""
        return self.wind is None and self.battery is None and not self.affected.any()

    def mission(self, index: int) -> FaultDraws:
        """One mission of stacked draws."""
        return FaultDraws(
            outage=self.outage[index],
            burst_loss=self.burst_loss[index],
            snr_error_db=self.snr_error_db[index],
            poll_missed=self.poll_missed[index],
            gps_error_m=self.gps_error_m[index],
            wind=self.wind,
            battery=self.battery,
        )


def no_faults(n_slots: int, n_sensors: int) -> FaultDraws:
    """Draws of a fault-free mission."""
    return FaultDraws(
        outage=np.zeros((n_slots, n_sensors), dtype=bool),
        burst_loss=np.zeros((n_slots, n_sensors), dtype=bool),
        snr_error_db=np.zeros((n_slots, n_sensors)),
        poll_missed=np.zeros(n_slots, dtype=bool),
        gps_error_m=np.zeros((n_slots, 2)),
    )


def _columns(params: FaultParams, sensor_names: Sequence[str]) -> np.ndarray:
    """Indices of the sensors a fault applies to (all when it lists none)."""
    wanted = getattr(params, "sensors", None)
    if wanted is None:
        return np.arange(len(sensor_names))
    unknown = [n for n in wanted if n not in sensor_names]
    if unknown:
        raise ValueError(
            f"sensors: {unknown[0]!r} is not a sensor of the scenario; "
            f"allowed: {', '.join(sensor_names)}"
        )
    return np.array([list(sensor_names).index(n) for n in wanted], dtype=int)


def _draw_one(
    params: FaultParams,
    arrays: dict[str, np.ndarray],
    sensor_names: Sequence[str],
    slot_s: float,
    rng: np.random.Generator,
) -> None:
    """Add one fault's draws into ``arrays`` (mission axis of length 1)."""
    n_slots = arrays["poll_missed"].shape[1]
    cols = _columns(params, sensor_names)
    if isinstance(params, OutageParams):
        arrays["outage"][:, :, cols] |= outage_windows(rng, params, (1, n_slots, cols.size), slot_s)
    elif isinstance(params, GilbertElliottParams):
        lost = gilbert_elliott_loss(
            rng,
            params.p_good_to_bad,
            params.p_bad_to_good,
            params.loss_good,
            params.loss_bad,
            (1, cols.size, n_slots),
        )
        arrays["burst_loss"][:, :, cols] |= lost.transpose(0, 2, 1)
    elif isinstance(params, SnrErrorParams):
        rho = correlation_per_slot(params.correlation_s, slot_s)
        noise = ar1_normal(rng, (1, n_slots, cols.size), rho)
        arrays["snr_error_db"][:, :, cols] += params.bias_db + params.std_db * noise
    elif isinstance(params, MissedPollParams):
        if params.probability is not None:
            arrays["poll_missed"] |= rng.random((1, n_slots)) < params.probability
        else:
            assert params.p_good_to_bad is not None and params.p_bad_to_good is not None
            arrays["poll_missed"] |= gilbert_elliott_loss(
                rng, params.p_good_to_bad, params.p_bad_to_good, 0.0, 1.0, (1, n_slots)
            )
    elif isinstance(params, GpsErrorParams):
        rho = correlation_per_slot(params.correlation_s, slot_s)
        noise = ar1_normal(rng, (1, n_slots, 2), rho)
        arrays["gps_error_m"] += np.asarray(params.bias_m) + params.std_m * noise


def draw_faults(
    specs: Sequence[FaultEntry],
    n_slots: int,
    sensor_names: Sequence[str],
    slot_s: float,
    rng: np.random.Generator,
) -> FaultDraws:
    """Draw one mission's faults.

    Args:
        specs: the scenario's ``[[faults]]`` entries (kind + params), in file order.
        n_slots: number of slots T.
        sensor_names: (N,) sensor names, in mission order.
        slot_s: slot length [s].
        rng: the mission's fault generator (:func:`fault_rng`). Entry k draws from the k-th
            child generator, so adding or removing one entry leaves the others' draws as they
            were; with no entries ``rng`` is not used at all.

    Raises:
        ValueError: an entry is invalid or names an unknown sensor (one line).
    """
    base = no_faults(n_slots, len(sensor_names))
    arrays = {
        name: np.array(getattr(base, name))[None]
        for name in ("outage", "burst_loss", "snr_error_db", "poll_missed", "gps_error_m")
    }
    wind: Wind | None = None
    battery: Battery | None = None
    children = rng.spawn(len(specs)) if specs else []
    for index, (entry, child) in enumerate(zip(specs, children, strict=True)):
        try:
            params = fault_params(entry.kind, entry.params)
            _draw_one(params, arrays, sensor_names, slot_s, child)
        except ValueError as exc:
            raise ValueError(f"faults[{index}]: {exc}") from None
        if isinstance(params, WindParams):
            wind = Wind(params.speed_mps, params.from_deg)
        elif isinstance(params, BatteryParams):
            battery = Battery(
                params.capacity_wh * J_PER_WH, params.reserve_fraction, params.return_speed_mps
            )
    return FaultDraws(
        outage=arrays["outage"][0],
        burst_loss=arrays["burst_loss"][0],
        snr_error_db=arrays["snr_error_db"][0],
        poll_missed=arrays["poll_missed"][0],
        gps_error_m=arrays["gps_error_m"][0],
        wind=wind,
        battery=battery,
    )


def draw_uav_faults(
    specs: Sequence[FaultEntry],
    n_slots: int,
    sensor_names: Sequence[str],
    slot_s: float,
    seed: int,
    uav: int,
) -> FaultDraws:
    """UAV ``uav``'s faults in a fleet of scenario ``seed``: the towers' draws
    (:data:`TOWER_FIELDS`) shared by every UAV, the rest from the UAV's own generator
    (:func:`uav_fault_rng`). UAV 0 gets exactly :func:`draw_faults` with :func:`fault_rng`."""
    shared = draw_faults(specs, n_slots, sensor_names, slot_s, fault_rng(seed))
    if uav == 0:
        return shared
    own = draw_faults(specs, n_slots, sensor_names, slot_s, uav_fault_rng(seed, uav))
    return replace(own, **{name: getattr(shared, name) for name in TOWER_FIELDS})


def stack_draws(draws: Sequence[FaultDraws]) -> FaultDraws:
    """Several missions' draws (same T, N, wind and battery) on a leading missions axis."""
    if not draws:
        raise ValueError("stack_draws needs at least one mission")
    first = draws[0]
    if any(d.wind != first.wind or d.battery != first.battery for d in draws):
        raise ValueError("stacked missions must share their wind and battery")
    return FaultDraws(
        outage=np.stack([d.outage for d in draws]),
        burst_loss=np.stack([d.burst_loss for d in draws]),
        snr_error_db=np.stack([d.snr_error_db for d in draws]),
        poll_missed=np.stack([d.poll_missed for d in draws]),
        gps_error_m=np.stack([d.gps_error_m for d in draws]),
        wind=first.wind,
        battery=first.battery,
    )
