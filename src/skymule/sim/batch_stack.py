"""Stacking fixed-trajectory missions into one :class:`Batch` for the batched engine.

:func:`stack_missions` turns missions (and their policy specs) into the arrays the slot loops
of :mod:`skymule.sim.batch` (numpy) and :mod:`skymule.sim.compiled` run over: each distinct
track (and rate table) once, (U, K_max, N), with every mission pointing at one; per-mission
policy parameters, buffers, windows, fading and fault draws.

Policies covered: :data:`BATCH_POLICIES` (``greedy`` and ``hgad``); other policies and
autonomous missions run through the reference engine (see :mod:`skymule.experiments.run`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from skymule.errors import SkymuleError
from skymule.flight.paths import Track
from skymule.radio.rates import RateTable
from skymule.scenario import PolicySpec
from skymule.sim.batch_fading import stack_fading
from skymule.sim.batch_faults import BatchFaults, stack_faults
from skymule.world import Mission


@dataclass(frozen=True)
class PolicyParams:
    """Per-mission policy parameters the batched loop understands.

    Attributes:
        hgad: True for HGAD, False for Greedy.
        hover_threshold: HGAD trigger fraction of the peak rate (unused for Greedy).
        max_hover_s: HGAD longest hover [s] (unused for Greedy).
    """

    hgad: bool
    hover_threshold: float = 1.0
    max_hover_s: float = 0.0


BATCH_POLICIES: dict[str, Callable[[PolicySpec], PolicyParams]] = {
    "greedy": lambda spec: PolicyParams(hgad=False),
    "hgad": lambda spec: PolicyParams(
        True, spec.param("hover_threshold"), spec.param("max_hover_s")
    ),
}
"""Policies with a batched implementation: name -> parameters from the ``[policy]`` section."""


def batchable(mission: Mission, spec: PolicySpec) -> bool:
    """True if ``mission`` under ``spec`` can run in the batched engine.

    The numpy loop applies faults (:mod:`skymule.sim.batch_faults`) except a wind, which
    changes progress along the track: such missions run in the reference engine.
    """
    windy = mission.faults is not None and mission.faults.wind is not None
    return mission.track is not None and not windy and spec.name in BATCH_POLICIES


@dataclass(frozen=True)
class Batch:
    """B missions stacked for the slot loop (U distinct tracks, K_max samples, N sensors).

    Attributes:
        track_id: (B,) index of each mission's track in the track arrays.
        rate_bps: (U, K_max + 1, N) rate at each track sample [bit/s] (0 in padding).
        snr_db: (U, K_max, N) track SNR [dB] (NaN: no sample).
        snr_seen_db: (U, K_max, N) SNR as policies see it (NaN -> -inf) [dB].
        position_m: (U, K_max, 3) sample positions [m].
        peak_rate_bps: (U, N) largest rate per sensor over each track [bit/s].
        n_samples: (U,) track lengths K.
        hold_at_end: (U,) True: hold at the last sample; False: a trace that runs out.
        n_slots: (B,) slots per mission T.
        window_slots: (B,) slot from which nothing is served (the download window closed);
            n_slots where there is no window.
        slot_s: (B,) slot length [s].
        buffers_bit: (B, N) initial buffers [bit].
        hgad: (B,) True for HGAD missions, False for Greedy.
        threshold_bps: (B, N) HGAD trigger thresholds gamma_i [bit/s].
        max_hover_s: (B,) HGAD longest hover [s].
        fading_index: (F,) the missions with per-slot fading (F may be 0).
        fading_db: (T_max, N, F) their fading [dB] added to the SNR seen in slot t (0 past
            a mission's last slot).
        rate_model: (F,) index of each fading mission's rate model in ``rate_models``.
        rate_models: (rate table, bandwidth [Hz]) pairs turning faded SNR into rate.
        faults: the missions with ``[[faults]]`` and their draws (``docs/faults.md``).
    """

    track_id: np.ndarray
    rate_bps: np.ndarray
    snr_db: np.ndarray
    snr_seen_db: np.ndarray
    position_m: np.ndarray
    peak_rate_bps: np.ndarray
    n_samples: np.ndarray
    hold_at_end: np.ndarray
    n_slots: np.ndarray
    window_slots: np.ndarray
    slot_s: np.ndarray
    buffers_bit: np.ndarray
    hgad: np.ndarray
    threshold_bps: np.ndarray
    max_hover_s: np.ndarray
    fading_index: np.ndarray
    fading_db: np.ndarray
    rate_model: np.ndarray
    rate_models: tuple[tuple[RateTable, float], ...]
    faults: BatchFaults

    @property
    def size(self) -> int:
        return int(self.track_id.shape[0])


Params = TypeVar("Params")


def batched_params(
    factories: Mapping[str, Callable[[PolicySpec], Params]], spec: PolicySpec, engine: str
) -> Params:
    """A batched engine's parameters of a ``[policy]`` section, from ``factories`` (policy
    name -> parameters); the one-line SkymuleError naming ``engine`` if it has none."""
    factory = factories.get(spec.name)
    if factory is None:
        raise SkymuleError(
            f"policy.name = {spec.name!r} has no {engine}; allowed: {', '.join(sorted(factories))}"
        )
    return factory(spec)


def policy_params(spec: PolicySpec) -> PolicyParams:
    """The batched fixed-path engine's parameters of a ``[policy]`` section."""
    return batched_params(BATCH_POLICIES, spec, "batched engine")


def in_batches(groups: Iterable[list[int]], batch_size: int) -> Iterator[list[int]]:
    """Each group of mission indices (missions that can share a batch) cut into batches of at
    most ``batch_size``."""
    for indices in groups:
        for start in range(0, len(indices), batch_size):
            yield indices[start : start + batch_size]


def stack_missions(missions: Sequence[Mission], specs: Sequence[PolicySpec]) -> Batch:
    """Stack fixed-trajectory missions with the same number of sensors into a :class:`Batch`."""
    if not missions:
        raise ValueError("stack_missions needs at least one mission")
    n_sensors = {m.n_sensors for m in missions}
    if len(n_sensors) != 1:
        raise ValueError(f"a batch needs one sensor count, got {sorted(n_sensors)}")
    n = n_sensors.pop()
    keys: dict[tuple[int, int, float], int] = {}
    unique: list[Mission] = []
    tracks: list[Track] = []  # unique[u].track
    track_id = np.empty(len(missions), np.int64)
    for b, mission in enumerate(missions):
        if mission.track is None:
            raise SkymuleError("the batched engine needs fixed trajectories (trajectory.mode)")
        if mission.faults is not None and mission.faults.wind is not None:
            raise SkymuleError(
                "the batched engine does not apply a wind fault: run such missions with "
                "skymule.sim.run.run_mission (the reference engines)"
            )
        key = (id(mission.track), id(mission.rate_table), mission.bandwidth_hz)
        if key not in keys:
            keys[key] = len(unique)
            unique.append(mission)
            tracks.append(mission.track)
        track_id[b] = keys[key]
    # one padding row past the longest track: where a used-up trace points
    k_max = max(t.n_samples for t in tracks) + 1
    rate = np.zeros((len(unique), k_max, n))
    snr = np.full((len(unique), k_max, n), np.nan)
    snr_seen = np.full((len(unique), k_max, n), -np.inf)
    position = np.zeros((len(unique), k_max, 3))
    peak = np.zeros((len(unique), n))
    for u, mission in enumerate(unique):
        track = mission.track
        assert track is not None
        k = track.n_samples
        rate[u, :k] = mission.rate_bps(track.snr_db)
        snr[u, :k] = track.snr_db
        snr_seen[u, :k] = np.nan_to_num(track.snr_db, nan=-np.inf)
        position[u, :k] = track.position_m
        peak[u] = mission.peak_rate_bps()
    # one lookup per distinct spec object: sweeps and comparisons repeat a few specs many times
    by_spec: dict[int, PolicyParams] = {}
    for spec in specs:
        if id(spec) not in by_spec:
            by_spec[id(spec)] = policy_params(spec)
    params = [by_spec[id(spec)] for spec in specs]
    thresholds = np.array([p.hover_threshold for p in params])
    fading_index, fading, rate_model, rate_models = stack_fading(missions, n)
    return Batch(
        track_id=track_id,
        rate_bps=rate,
        snr_db=snr,
        snr_seen_db=snr_seen,
        position_m=position,
        peak_rate_bps=peak,
        n_samples=np.array([t.n_samples for t in tracks], np.int64),
        hold_at_end=np.array([t.hold_at_end for t in tracks], bool),
        n_slots=np.array([m.n_slots for m in missions], np.int64),
        window_slots=np.array(
            [m.n_slots if m.window_slots is None else m.window_slots for m in missions], np.int64
        ),
        slot_s=np.array([m.slot_s for m in missions], float),
        buffers_bit=np.array([m.buffers_bit for m in missions], float).reshape(-1, n),
        hgad=np.array([p.hgad for p in params], bool),
        threshold_bps=thresholds[:, None] * peak[track_id],
        max_hover_s=np.array([p.max_hover_s for p in params], float),
        fading_index=fading_index,
        fading_db=fading,
        faults=stack_faults(missions, n),
        rate_model=rate_model,
        rate_models=rate_models,
    )


def mission_geometry(
    missions: Sequence[Mission], n_sensors: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What the summaries need of each mission besides its slots: home (B, 2) [m] (NaN: none),
    hover points (B, N, 2) [m] (NaN: unknown), visit radius (B,) [m], AADM window (B,) [s]."""
    home = _rows_by_object([m.home_m for m in missions], (2,))
    hover = _rows_by_object([m.hover_points_m for m in missions], (n_sensors, 2))
    radius = np.array([m.visit_radius_m for m in missions], float)
    window = np.array([m.score_window_s for m in missions], float)
    return home, hover, radius, window


def _rows_by_object(values: Sequence[np.ndarray | None], shape: tuple[int, ...]) -> np.ndarray:
    """(B, *shape) array of ``values`` (None: NaN), each distinct array object copied once:
    missions built from one geometry share these arrays."""
    first: dict[int, int] = {}
    which = np.array([first.setdefault(id(v), len(first)) for v in values], np.int64)
    distinct = np.full((len(first), *shape), np.nan)
    for row in np.unique(which, return_index=True)[1]:
        value = values[row]
        if value is not None:
            distinct[which[row]] = value
    return distinct[which]
