"""Several UAVs from scenario to results: build the fleet, run its policy, summarise, write.

The fleet counterpart of :mod:`skymule.tasks.simulate`. ``summary.json`` of a fleet run holds the
fleet totals at the top level (the keys of a single-UAV summary that make sense for a fleet:
downloads, completion, per-sensor downloads) plus ``uavs``: one single-UAV summary per UAV
(its own downloads, distance, energy, landing) with ``lost_slots``, the slots in which it
chose a sensor another UAV won. ``slots.csv`` has one row per UAV per slot: a ``uav`` column,
the single-UAV columns, ``chosen`` (the sensor its policy asked for) and ``lost`` (1 where
another UAV won it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.bounds.result import MissionBound
from skymule.errors import SkymuleError
from skymule.io import atomic
from skymule.io.runs import slots_frame, write_run
from skymule.metrics.flights import Flights
from skymule.metrics.summary import summarize
from skymule.policies import batch_policy
from skymule.policies.base import BatchPolicy, Policy
from skymule.policies.batched import PerFleet, PerMission, policy_names
from skymule.policies.fleet import COORDINATED, Coordinated
from skymule.rules.contract import NO_SENSOR
from skymule.scenario import Scenario
from skymule.sim.fleet import Fleet, build_fleet
from skymule.sim.run import run_missions
from skymule.tasks.compare import (
    COMPARISON_CSV,
    distinct_labels,
    policy_folder,
    with_gap,
    write_bound,
)
from skymule.units import BITS_PER_MBIT

FLEET_POLICIES = (COORDINATED,)
"""Policies that decide for the whole fleet (any single-UAV policy runs independently)."""


def make_fleet_policy(fleet: Fleet, name: str | None = None) -> BatchPolicy:
    """``coordinated``, or each UAV's own policy run independently (``name`` overrides all):
    one batched policy over the fleet's K UAV columns."""
    if (name or fleet.policies[0].name) == COORDINATED and (
        name is not None or all(spec.name == COORDINATED for spec in fleet.policies)
    ):
        return PerFleet([Coordinated()], fleet.size)
    specs = [
        spec if name is None else spec.model_copy(update={"name": name}) for spec in fleet.policies
    ]
    if any(spec.name == COORDINATED for spec in specs):
        raise SkymuleError(
            "policy.name = 'coordinated' decides for the whole fleet: set it in the scenario's "
            "[policy] (or --policy coordinated) with no other policy in any [uavs.policy]"
        )
    return batch_policy(specs)


def run_fleet(fleet: Fleet, policy: BatchPolicy | Sequence[Policy]) -> Flights:
    """Run a fleet mission under ``policy`` (one batched policy over the UAV columns, or one
    per-mission policy per UAV): every UAV decides every slot, over shared buffers."""
    if isinstance(policy, Sequence):
        labels = [f"{p.name} ({uav})" for p, uav in zip(policy, fleet.names, strict=True)]
        policy = PerMission(policy, labels)
    return run_missions(list(fleet.missions), policy, fleet=np.zeros(fleet.size, np.int64))


def fleet_summary(fleet: Fleet, log: Flights, policy: str) -> dict[str, Any]:
    """``summary.json`` of a fleet run (module docstring)."""
    mission = fleet.missions[0]
    per_uav = []
    assert log.lost is not None or fleet.size == 1
    lost_slots = np.zeros(fleet.size, np.int64) if log.lost is None else log.lost.sum(axis=1)
    for name, uav_log, lost in zip(fleet.names, log.missions(), lost_slots, strict=True):
        part = summarize(uav_log, fleet.scenario.name)
        # a UAV's log holds the shared buffers: its own share per sensor is what it served
        own = np.zeros(mission.n_sensors)
        served = uav_log.served != NO_SENSOR
        np.add.at(own, uav_log.served[served], uav_log.downloaded_bit[served])
        part["per_sensor_downloaded_mbit"] = dict(
            zip(mission.sensor_names, (own / BITS_PER_MBIT).tolist(), strict=True)
        )
        per_uav.append({"uav": name, **part, "lost_slots": int(lost)})
    # the fleet's per-sensor total in one pass over all UAVs' slots (not the sum of the shares
    # above: another summation order, so other last bits than the fleet summaries so far)
    by_sensor = np.zeros(mission.n_sensors)
    for uav_log in log.missions():
        served = uav_log.served
        np.add.at(
            by_sensor, served[served != NO_SENSOR], uav_log.downloaded_bit[served != NO_SENSOR]
        )
    downloaded = float(by_sensor.sum()) / BITS_PER_MBIT
    total_buffer = float(mission.buffers_bit.sum()) / BITS_PER_MBIT
    return {
        "scenario": fleet.scenario.name,
        "policy": policy,
        "n_uavs": fleet.size,
        "mission_time_s": mission.n_slots * mission.slot_s,
        "slots": int(log.n_run[0]),
        "slot_s": mission.slot_s,
        "total_downloaded_mbit": float(downloaded),
        "total_buffer_mbit": total_buffer,
        "per_sensor_downloaded_mbit": dict(
            zip(mission.sensor_names, (by_sensor / BITS_PER_MBIT).tolist(), strict=True)
        ),
        "per_sensor_buffer_mbit": dict(
            zip(mission.sensor_names, (mission.buffers_bit / BITS_PER_MBIT).tolist(), strict=True)
        ),
        "completion": float(downloaded / total_buffer) if total_buffer > 0 else 1.0,
        "lost_slots": int(lost_slots.sum()),
        "distance_m": float(sum(u["distance_m"] for u in per_uav)),
        "energy_kj": float(sum(u["energy_kj"] for u in per_uav)),
        "landed_within_5m": all(bool(u.get("landed_within_5m", True)) for u in per_uav),
        "uavs": per_uav,
    }


def fleet_slots_frame(fleet: Fleet, log: Flights) -> pd.DataFrame:
    """``slots.csv`` of a fleet run: one row per UAV per slot (module docstring)."""
    names = np.array([*fleet.missions[0].sensor_names, ""], dtype=object)
    n_sensors = fleet.missions[0].n_sensors
    frames = []
    for index, (name, uav_log) in enumerate(zip(fleet.names, log.missions(), strict=True)):
        frame = slots_frame(uav_log, fleet.missions[index].frame)
        chosen = uav_log.served if log.chosen is None else log.chosen[index, : uav_log.n_slots]
        lost = np.zeros(uav_log.n_slots, bool) if log.lost is None else log.lost[index]
        frame.insert(0, "uav", name)
        after_served = list(frame.columns).index("served") + 1
        frame.insert(after_served, "chosen", names[np.where(chosen < 0, n_sensors, chosen)])
        frame.insert(after_served + 1, "lost", lost[: uav_log.n_slots].astype(int))
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


@dataclass(frozen=True)
class FleetResult:
    """A finished fleet mission: what was run, what happened, and its summary."""

    fleet: Fleet
    log: Flights
    summary: dict[str, Any]

    def write(self, out_dir: Path) -> None:
        """Write the run folder (summary.json, slots.csv with a uav column, scenario.json)."""
        write_run(
            out_dir,
            self.summary,
            fleet_slots_frame(self.fleet, self.log),
            self.fleet.scenario.to_toml_dict(),
        )


def simulate_fleet(
    scenario: Scenario, policy: str | None = None, fleet: Fleet | None = None
) -> FleetResult:
    """Run ``scenario``'s fleet under its policies, or every UAV under ``policy``.

    Pass a prebuilt ``fleet`` to compare several policies on identical signal draws.
    """
    fleet = build_fleet(scenario) if fleet is None else fleet
    chosen = make_fleet_policy(fleet, policy)
    log = run_fleet(fleet, chosen)
    return FleetResult(fleet, log, fleet_summary(fleet, log, fleet_policy_name(chosen, fleet)))


@dataclass(frozen=True)
class FleetComparison:
    """Several policies on one built fleet (identical draws), with the K-UAV upper bound.

    Attributes:
        results: one finished run per policy, in the order asked.
        bound: the fleet's upper bound, or None (``note`` says why).
        note: why there is no bound ("" when there is one).
    """

    fleet: Fleet
    results: tuple[FleetResult, ...]
    bound: MissionBound | None
    note: str = ""

    def rows(self) -> list[dict[str, Any]]:
        """One row per policy: the fleet totals (no per-UAV or per-sensor detail) + the gap."""
        return [
            with_gap(
                {k: v for k, v in result.summary.items() if not isinstance(v, dict | list)},
                self.bound,
            )
            for result in self.results
        ]


def compare_fleet(scenario: Scenario, policies: Sequence[str]) -> FleetComparison:
    """Run ``scenario``'s fleet under each of ``policies`` on one built fleet, with its bound."""
    from skymule.bounds.fleet import fleet_bound
    from skymule.bounds.result import BoundError

    fleet = build_fleet(scenario)
    try:
        bound, note = fleet_bound(fleet), ""
    except BoundError as exc:
        bound, note = None, str(exc)
    results = [simulate_fleet(scenario, name, fleet=fleet) for name in policies]
    return FleetComparison(fleet, tuple(distinct_labels(results, policies)), bound, note)


def write_fleet_compare(comparison: FleetComparison, out: Path) -> list[Path]:
    """Write one run folder per policy, comparison.csv and bound.json; the top-level files."""
    (out / COMPARISON_CSV).unlink(missing_ok=True)  # a rewrite cut short is incomplete too
    for result in comparison.results:
        result.write(out / policy_folder(result.summary["policy"]))
    written = [out / COMPARISON_CSV]
    if comparison.bound is not None:
        written.append(write_bound(out, comparison.bound))
    table = pd.DataFrame(comparison.rows())  # the index last (io.runs.check_complete_comparison)
    atomic.write_with(written[0], lambda tmp: table.to_csv(tmp, index=False))
    return written


def fleet_policy_name(policy: BatchPolicy, fleet: Fleet) -> str:
    """The name a fleet run's summary gives its policy (one name, or 'a+b' for several)."""
    from skymule.policies.batched import joined_name

    return joined_name(list(policy_names(policy, fleet.size)))
