"""Run folders: what a run writes, and reading it back (plots and reports read only these).

A run folder holds ``summary.json``, ``slots.csv`` (one row a slot) and ``scenario.json``
(the validated scenario, so a result always travels with what produced it).

Reading validates all three against one schema (:mod:`skymule.io.runschema`: pydantic for the
JSON files, column/type/length checks for the slot table) and then against each other (totals,
slot sums, buffers, sensors), so a damaged or hand-edited folder is one line naming the file,
the row/column and what is allowed, never a traceback and never a figure drawn from part of
the slots. Every reader (``plot``, ``report``, ``export``, the fleet report) goes through
:func:`read_run`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.geo import LocalFrame
from skymule.io import atomic
from skymule.io.runschema import (
    check_run_whole,
    check_slots,
    validate_scenario_json,
    validate_summary,
)
from skymule.io.textfiles import parse_json, read_text
from skymule.metrics.flights import NO_SENSOR, MissionLog
from skymule.metrics.summary import power_w, speed_mps, step_lengths_m
from skymule.units import BITS_PER_MBIT

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
    if log.affected is not None:  # only with [[faults]]: fault-free folders are unchanged
        columns["fault"] = log.affected.astype(int)
    if log.battery_used_j is not None:  # a battery fault: what the pack has paid so far
        columns["battery_used_kj"] = log.battery_used_j / 1e3
    return pd.DataFrame(columns)


def write_run(
    out_dir: Path, summary: dict[str, Any], slots: pd.DataFrame, scenario: dict[str, Any]
) -> None:
    """Write a run folder (creating it); each file whole or not at all, summary.json last (a
    folder is a run folder once it has summary.json and slots.csv)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic.write_text(out_dir / SLOTS_FILE, slots.to_csv(index=False, float_format="%.10g"))
    atomic.write_text(out_dir / SCENARIO_FILE, json.dumps(scenario, indent=2))
    atomic.write_text(out_dir / SUMMARY_FILE, json.dumps(summary, indent=2))


COMPARISON_FILE = "comparison.csv"
"""The index of a compare folder, written after every run folder in it."""


def check_complete_comparison(folder: Path) -> None:
    """Refuse, in one line, a compare folder whose index (``comparison.csv``) is missing: a
    compare interrupted before its last write, whose run folders may be only some of the
    policies it was asked for."""
    if not (folder / COMPARISON_FILE).is_file():
        raise SkymuleError(
            f"{folder}: an incomplete compare folder (run folders but no {COMPARISON_FILE}, "
            "which compare writes last: it was interrupted); run the compare again with this "
            "--out, or report one run folder inside it"
        )


def is_run_dir(path: Path) -> bool:
    return (path / SUMMARY_FILE).is_file() and (path / SLOTS_FILE).is_file()


def _read_json(path: Path) -> Any:
    text = read_text(path, "run file")
    try:
        return parse_json(text)
    except ValueError as exc:
        raise SkymuleError(
            f"{path}: not valid JSON ({exc}); rewrite the run with `skymule run`"
        ) from None


def read_run(run_dir: Path) -> tuple[dict[str, Any], pd.DataFrame]:
    """Summary and slot table of a run folder, validated; a clear one-line error if damaged.

    ``scenario.json`` is validated too when present (figures draw the site from it).
    """
    if not is_run_dir(run_dir):
        raise SkymuleError(
            f"{run_dir}: not a run folder (expected {SUMMARY_FILE} and {SLOTS_FILE}; "
            "make one with `skymule run SCENARIO --out DIR`)"
        )
    summary_path = run_dir / SUMMARY_FILE
    summary = validate_summary(_read_json(summary_path), str(summary_path))
    slots_path = run_dir / SLOTS_FILE
    try:
        slots = pd.read_csv(
            slots_path,
            keep_default_na=False,
            na_values=[""],
            encoding="utf-8",
            dtype={"served": str},  # sensor names stay text, even "1" or an all-empty column
        )
    except UnicodeDecodeError as exc:
        raise SkymuleError(
            f"{slots_path}: not a UTF-8 text file (bad byte at offset {exc.start})"
        ) from None
    except pd.errors.EmptyDataError:
        raise SkymuleError(
            f"{slots_path}: empty file; expected a header and one row a slot"
        ) from None
    except (OSError, ValueError) as exc:
        raise SkymuleError(
            f"{slots_path}: cannot read ({str(exc).strip().splitlines()[0]})"
        ) from None
    slots = check_slots(slots, summary, str(slots_path))
    check_run_whole(summary, slots, read_run_scenario(run_dir), run_dir)
    return summary, slots


def read_run_scenario(run_dir: Path) -> dict[str, Any]:
    """The run's ``scenario.json`` (validated as a scenario), or ``{}`` when it has none."""
    path = run_dir / SCENARIO_FILE
    if not path.is_file():
        return {}
    return validate_scenario_json(_read_json(path), str(path), run_dir)


def sensor_names_of(slots: pd.DataFrame) -> list[str]:
    return [c.removeprefix("snr_db_") for c in slots.columns if c.startswith("snr_db_")]
