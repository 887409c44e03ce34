"""Run folders: what a run writes, and reading it back (plots and reports read only these).

A run folder holds ``summary.json``, ``slots.csv`` (one row a slot) and ``scenario.json``
(the validated scenario, so a result always travels with what produced it).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.geo import LocalFrame
from skymule.metrics import BITS_PER_MBIT, power_w, speed_mps, step_lengths_m
from skymule.sim.log import NO_SENSOR, MissionLog

SUMMARY_FILE = "summary.json"
SLOTS_FILE = "slots.csv"
SCENARIO_FILE = "scenario.json"


def slots_frame(log: MissionLog, frame: LocalFrame) -> pd.DataFrame:
    """One row per slot with the columns documented in the README."""
    lat, lon = frame.to_latlon(log.position_m[:, 0], log.position_m[:, 1])
    names = np.array([*log.sensor_names, ""], dtype=object)
    columns: dict[str, Any] = {
        "t_s": np.arange(log.n_slots) * log.slot_s,
        "x_m": log.position_m[:, 0],
        "y_m": log.position_m[:, 1],
        "z_m": log.position_m[:, 2],
        "lat": lat,
        "lon": lon,
        "served": names[np.where(log.served == NO_SENSOR, len(log.sensor_names), log.served)],
    }
    for index, name in enumerate(log.sensor_names):
        columns[f"snr_db_{name}"] = log.snr_db[:, index]
    for index, name in enumerate(log.sensor_names):
        columns[f"remaining_mbit_{name}"] = log.remaining_bit[:, index] / BITS_PER_MBIT
    served_rate = np.where(
        log.served == NO_SENSOR,
        0.0,
        np.take_along_axis(log.rate_bps, np.maximum(log.served, 0)[:, None], axis=1)[:, 0],
    )
    columns["rate_mbps"] = served_rate / BITS_PER_MBIT
    columns["downloaded_mbit"] = log.downloaded_bit / BITS_PER_MBIT
    columns["hovering"] = log.hovering.astype(int)
    columns["distance_m"] = np.cumsum(step_lengths_m(log))
    columns["speed_mps"] = speed_mps(log)
    columns["power_w"] = power_w(log)
    return pd.DataFrame(columns)


def _atomic_write(path: Path, text: str) -> None:
    # write-then-rename: a run killed mid-write never leaves a truncated file behind
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_run(
    out_dir: Path, summary: dict[str, Any], slots: pd.DataFrame, scenario: dict[str, Any]
) -> None:
    """Write a run folder (creating it)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    _atomic_write(out_dir / SLOTS_FILE, slots.to_csv(index=False, float_format="%.10g"))
    _atomic_write(out_dir / SCENARIO_FILE, json.dumps(scenario, indent=2))
    _atomic_write(out_dir / SUMMARY_FILE, json.dumps(summary, indent=2))


REQUIRED_SLOT_COLUMNS = (
    "t_s",
    "x_m",
    "y_m",
    "z_m",
    "served",
    "rate_mbps",
    "downloaded_mbit",
    "hovering",
    "distance_m",
)
"""slots.csv columns every reader of a run folder relies on (plus snr_db_<name> per sensor)."""

REQUIRED_SUMMARY_KEYS = (
    "scenario",
    "policy",
    "slots",
    "total_downloaded_mbit",
    "per_sensor_downloaded_mbit",
    "per_sensor_buffer_mbit",
)
"""summary.json keys every reader of a run folder relies on."""


def is_run_dir(path: Path) -> bool:
    return (path / SUMMARY_FILE).is_file() and (path / SLOTS_FILE).is_file()


def read_run(run_dir: Path) -> tuple[dict[str, Any], pd.DataFrame]:
    """Summary and slot table of a run folder; a clear error if it is not one."""
    if not is_run_dir(run_dir):
        raise SkymuleError(
            f"{run_dir}: not a run folder (expected {SUMMARY_FILE} and {SLOTS_FILE}; "
            "make one with `skymule run SCENARIO --out DIR`)"
        )
    try:
        summary = json.loads((run_dir / SUMMARY_FILE).read_text())
        slots = pd.read_csv(run_dir / SLOTS_FILE, keep_default_na=False, na_values=[""])
    except (OSError, ValueError) as exc:
        raise SkymuleError(f"{run_dir}: cannot read run files ({exc})") from None
    missing_keys = [
        k for k in REQUIRED_SUMMARY_KEYS if not isinstance(summary, dict) or k not in summary
    ]
    if missing_keys:
        raise SkymuleError(
            f"{run_dir / SUMMARY_FILE}: missing {', '.join(missing_keys)}; "
            "not written by `skymule run` (or damaged)"
        )
    missing_columns = [c for c in REQUIRED_SLOT_COLUMNS if c not in slots.columns]
    if missing_columns or not sensor_names_of(slots):
        missing = missing_columns or ["snr_db_<sensor>"]
        raise SkymuleError(
            f"{run_dir / SLOTS_FILE}: missing column(s) {', '.join(missing)}; "
            "not written by `skymule run` (or damaged)"
        )
    slots["served"] = slots["served"].fillna("").astype(str)
    return summary, slots


def sensor_names_of(slots: pd.DataFrame) -> list[str]:
    return [c.removeprefix("snr_db_") for c in slots.columns if c.startswith("snr_db_")]
