"""What a fleet report reads: run folders of several UAVs (``docs/fleet.md``), files only.

A fleet run folder is a run folder whose ``slots.csv`` has a ``uav`` column (one row per UAV
per slot) and whose ``summary.json`` has the fleet totals plus ``uavs``, one single-UAV
summary per UAV (:mod:`skymule.tasks.fleet`). On top of the checks every run folder gets
(:func:`skymule.io.runs.read_run`), the two files must agree on the fleet: the same UAV
names, every UAV with the summary's ``slots`` rows, and each UAV's download in the slot table
equal to its summary's. A damaged folder is one line naming the file and what is wrong.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.io.runs import (
    SLOTS_FILE,
    SUMMARY_FILE,
    check_complete_comparison,
    is_run_dir,
    read_run,
)
from skymule.io.runschema import validate_summary
from skymule.io.textfiles import parse_json
from skymule.report.inputs import RunData, run_data

#: Slack between a UAV's download summed over slots.csv and its summary.json entry [Mbit]:
#: slots.csv keeps 10 significant digits, so 500 slots of ~10 Mbit add up to ~1e-6 Mbit.
DOWNLOAD_TOLERANCE_MBIT = 1e-3


@dataclass(frozen=True)
class FleetRun:
    """One fleet run folder's files: the run (all UAVs' slots) and its UAVs, in order.

    Attributes:
        run: the folder's files; ``run.slots`` holds every UAV's rows.
        uavs: the UAV names, in ``summary.json``'s order.
        per_uav: each UAV's summary (``summary.json`` ``uavs``), in the same order.
    """

    run: RunData
    uavs: tuple[str, ...]
    per_uav: tuple[dict[str, Any], ...]

    @property
    def label(self) -> str:
        return self.run.label

    def slots_of(self, uav: str) -> pd.DataFrame:
        """One UAV's rows of slots.csv, in time order, re-indexed from 0."""
        return self.run.slots[self.run.slots["uav"] == uav].reset_index(drop=True)

    def sensor_mbit(self) -> pd.DataFrame:
        """Mbit each UAV downloaded from each sensor (UAVs x sensors), summed over slots.csv.

        Read off the slot table: a UAV's own summary lists the shared buffers' per-sensor
        downloads, which are the fleet's, not that UAV's.
        """
        slots = self.run.slots
        served = slots[slots["served"] != ""]
        table = served.groupby(["uav", "served"])["downloaded_mbit"].sum().unstack(fill_value=0)
        return table.reindex(
            index=list(self.uavs), columns=self.run.sensor_names, fill_value=0.0
        ).astype(float)


def _header(slots_path: Path) -> list[str]:
    """The column names of slots.csv (empty if unreadable: read_run then names the problem)."""
    try:
        with slots_path.open(newline="", encoding="utf-8") as handle:
            return next(csv.reader(handle), [])
    except (OSError, UnicodeDecodeError, csv.Error):
        return []


def _summary_uavs(summary_path: Path) -> Any:
    """``summary.json``'s ``uavs`` entry, or None (also when unreadable: read_run says why)."""
    try:
        data = parse_json(summary_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return data.get("uavs") if isinstance(data, dict) else None


def is_fleet_run(run_dir: Path) -> bool:
    """True when ``run_dir`` is a run of several UAVs (``uav`` column or ``uavs`` summary)."""
    if not is_run_dir(run_dir):
        return False
    return (
        "uav" in _header(run_dir / SLOTS_FILE) or _summary_uavs(run_dir / SUMMARY_FILE) is not None
    )


def holds_fleet_runs(folder: Path) -> bool:
    """True for a fleet run folder or a compare folder of fleet runs; False for single-UAV
    ones. A compare folder mixing the two is one line (their reports differ)."""
    if is_run_dir(folder):
        return is_fleet_run(folder)
    if not folder.is_dir():
        return False
    children = sorted(p for p in folder.iterdir() if is_run_dir(p))
    fleets = [p.name for p in children if is_fleet_run(p)]
    singles = [p.name for p in children if p.name not in fleets]
    if fleets and singles:
        raise SkymuleError(
            f"{folder}: mixes runs of several UAVs ({', '.join(fleets)}) with single-UAV runs "
            f"({', '.join(singles)}); one report covers one kind: report each run folder "
            f"(`skymule report {folder / fleets[0]}`) or move one kind out"
        )
    return bool(fleets)


def _uav_entries(summary: dict[str, Any], source: str) -> list[dict[str, Any]]:
    """The ``uavs`` list of a fleet summary, each entry checked as a single-UAV summary."""
    entries = summary.get("uavs")
    if not isinstance(entries, list) or not entries:
        raise SkymuleError(
            f"{source}: no 'uavs' list (one summary per UAV) but slots.csv has a uav column; "
            "rewrite the run with `skymule run`"
        )
    for index, entry in enumerate(entries):
        where = f"{source}: uavs[{index}]"
        if not isinstance(entry, dict) or not isinstance(entry.get("uav"), str) or not entry["uav"]:
            raise SkymuleError(f"{where}: expected an object with a 'uav' name (text)")
        validate_summary(entry, where)
    names = [str(entry["uav"]) for entry in entries]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise SkymuleError(f"{source}: uavs: names must be unique; repeated: {', '.join(repeated)}")
    n_uavs = summary.get("n_uavs", len(entries))
    if n_uavs != len(entries):
        raise SkymuleError(
            f"{source}: n_uavs = {n_uavs!r} but 'uavs' lists {len(entries)} UAVs "
            f"({', '.join(names)})"
        )
    return entries


def _check_uav_names(uav: pd.Series, names: list[str], source: str) -> pd.Series:
    """slots.csv's ``uav`` column as text, each cell one of ``names`` (summary.json's)."""
    text = uav.fillna("").astype(str)
    unknown = ~text.isin(names).to_numpy(dtype=bool)
    if unknown.any():
        index = int(np.argmax(unknown))
        shown = "an empty cell" if text.iloc[index] == "" else repr(text.iloc[index])
        raise SkymuleError(
            f"{source}: data row {index + 1}, column 'uav': {shown} is not allowed; allowed: "
            f"one of summary.json's uavs ({', '.join(names)})"
        )
    return text


def _precheck_uav_column(slots_path: Path, summary_path: Path) -> None:
    """The ``uav`` cells against summary.json's names, before :func:`read_run`: its row count
    is the summary's ``slots`` times the distinct ``uav`` cells, so a stray name would be
    reported as a wrong row count. Skipped when either file does not read (read_run says why).
    """
    entries = _summary_uavs(summary_path)
    if not isinstance(entries, list):
        return
    names = [e["uav"] for e in entries if isinstance(e, dict) and isinstance(e.get("uav"), str)]
    if len(names) != len(entries) or len(set(names)) != len(names):
        return  # a malformed entry or a repeated name: named after read_run (_uav_entries)
    try:
        column = pd.read_csv(
            slots_path, usecols=["uav"], dtype=str, keep_default_na=False, encoding="utf-8"
        )["uav"]
    except (OSError, UnicodeDecodeError, ValueError):  # pandas' parse errors are ValueErrors
        return
    _check_uav_names(column, names, str(slots_path))


def _check_uav_rows(
    slots: pd.DataFrame, summary: dict[str, Any], names: list[str], source: str
) -> None:
    """slots.csv's ``uav`` column names exactly the summary's UAVs, each with ``slots`` rows."""
    text = _check_uav_names(slots["uav"], names, source)
    counts = text.value_counts()
    expected = int(summary["slots"])
    for name in names:
        rows = int(counts.get(name, 0))
        if rows != expected:
            raise SkymuleError(
                f"{source}: UAV {name!r} has {rows} rows, expected summary.json's slots = "
                f"{expected} per UAV; the file is truncated or belongs to another run"
            )
    times = {name: slots.loc[(text == name).to_numpy(), "t_s"].to_numpy(float) for name in names}
    first = names[0]
    for name in names[1:]:
        differ = times[name] != times[first]
        if differ.any():
            index = int(np.flatnonzero((text == name).to_numpy())[int(np.argmax(differ))])
            raise SkymuleError(
                f"{source}: data row {index + 1}, column 't_s': {float(times[name][differ][0])!r}"
                f" is not allowed; allowed: {float(times[first][differ][0])!r} (the same slot's "
                f"time as UAV {first!r}: every UAV flies the same slots)"
            )


def _check_downloads(
    slots: pd.DataFrame, entries: list[dict[str, Any]], slots_path: Path, summary_path: Path
) -> None:
    """Each UAV's download in slots.csv equals its summary.json entry (same run)."""
    sums = slots.groupby(slots["uav"].astype(str))["downloaded_mbit"].sum()
    for entry in entries:
        in_slots = float(sums.get(entry["uav"], 0.0))
        in_summary = float(entry["total_downloaded_mbit"])
        if abs(in_slots - in_summary) > DOWNLOAD_TOLERANCE_MBIT + 1e-9 * abs(in_summary):
            raise SkymuleError(
                f"{slots_path}: UAV {entry['uav']!r} downloaded {in_slots:.3f} Mbit in its rows "
                f"but {summary_path} says {in_summary:.3f}; the files come from different runs"
            )


def load_fleet_run(run_dir: Path, label: str | None = None) -> FleetRun:
    """Read a fleet run folder, validated (one clear line if it is damaged)."""
    slots_path, summary_path = run_dir / SLOTS_FILE, run_dir / SUMMARY_FILE
    header = _header(slots_path)
    if header and "uav" not in header:  # before read_run: its row count assumes one UAV
        uavs = _summary_uavs(summary_path)
        listed = len(uavs) if isinstance(uavs, list) else "several"
        raise SkymuleError(
            f"{slots_path}: missing column 'uav'; summary.json lists {listed} UAVs and a run "
            "of several UAVs has one row per UAV per slot (rewrite it with `skymule run`)"
        )
    _precheck_uav_column(slots_path, summary_path)
    summary, slots = read_run(run_dir)
    entries = _uav_entries(summary, str(summary_path))
    names = [str(entry["uav"]) for entry in entries]
    _check_uav_rows(slots, summary, names, str(slots_path))
    slots = slots.assign(uav=slots["uav"].astype(str))
    _check_downloads(slots, entries, slots_path, summary_path)
    return FleetRun(run_data(run_dir, summary, slots, label), tuple(names), tuple(entries))


def load_fleet_input(path: Path) -> tuple[str, tuple[FleetRun, ...]]:
    """``("run", (one,))`` for a fleet run folder, ``("compare", runs)`` for a compare folder
    of fleet runs (one per policy, as ``skymule compare`` writes them)."""
    if is_run_dir(path):
        return "run", (load_fleet_run(path),)
    children = sorted(p for p in path.iterdir() if is_run_dir(p))
    check_complete_comparison(path)
    return "compare", tuple(load_fleet_run(child, child.name) for child in children)
