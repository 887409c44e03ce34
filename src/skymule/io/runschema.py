"""The schema of a run folder: what ``summary.json``, ``slots.csv`` and ``scenario.json`` hold.

Every reader of a run folder (``plot``, ``report``, ``export``) goes through
:func:`skymule.io.runs.read_run`, which checks the files here:

* ``summary.json``: :class:`RunSummary` (pydantic, strict numbers: no strings, no true/false);
  keys added by newer versions pass through unchecked.
* ``scenario.json``: the scenario schema itself (:class:`skymule.scenario.Scenario`).
* ``slots.csv``: the columns of :data:`FINITE_COLUMNS` (finite numbers), ``snr_db_<name>``
  (a number, ``inf``/``-inf`` or empty), the optional :data:`OPTIONAL_NUMBER_COLUMNS`
  (a number or empty), ``served`` (a sensor name or empty), ``hovering`` (0 or 1), and exactly
  ``summary.json``'s ``slots`` rows (a truncated file is an error, never a figure from part of
  the mission).

Then the folder is checked as a whole (:func:`check_run_whole`): the totals of
``summary.json`` equal its per-sensor sums and the sums over ``slots.csv``, no sensor gives
more than its buffer, and ``scenario.json`` names the sensors the other two files do.

Each problem is one line: the file, the row and column, the value and what is allowed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
import pandas as pd
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError

from skymule.errors import SkymuleError
from skymule.scenario import format_validation_error, scenario_from_dict


def _not_negative(value: float) -> float:
    if value < 0:  # NaN passes: a statistic that does not apply (e.g. no home point)
        raise ValueError("must be >= 0 (or NaN where it does not apply)")
    return value


Mbit = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Stat = Annotated[float, AfterValidator(_not_negative)]


class RunSummary(BaseModel):
    """The keys of ``summary.json`` that readers rely on (see ``skymule.metrics.summarize``)."""

    model_config = ConfigDict(extra="allow", frozen=True, strict=True)

    scenario: str
    policy: str
    slots: Annotated[int, Field(ge=1)]
    """Number of slots; ``slots.csv`` must have exactly this many rows."""
    slot_s: Annotated[float, Field(gt=0, allow_inf_nan=False)] = 1.0
    mission_time_s: Stat | None = None
    total_downloaded_mbit: Mbit
    total_buffer_mbit: Mbit | None = None
    per_sensor_downloaded_mbit: Annotated[dict[str, Mbit], Field(min_length=1)]
    per_sensor_buffer_mbit: Annotated[dict[str, Mbit], Field(min_length=1)]
    completion: Annotated[float, Field(ge=0, le=1)] | None = None
    handovers: Annotated[int, Field(ge=0)] | None = None
    hover_time_s: Stat | None = None
    distance_m: Stat | None = None
    energy_kj: Stat | None = None
    visit_order: list[str] | None = None
    landed_at_home: bool | None = None
    """Older runs; newer ones write landed_within_5m."""
    landed_within_5m: bool | None = None
    distance_to_home_m: Stat | None = None
    aadm_score: float | None = None
    aadm_t1_s: Stat | None = None
    aadm_s1: Stat | None = None
    aadm_s2: Annotated[float, Field(ge=0, le=100)] | None = None
    aadm_complete: bool | None = None


def validate_summary(data: Any, source: str) -> dict[str, Any]:
    """``summary.json`` contents, checked against :class:`RunSummary` (returned unchanged)."""
    if not isinstance(data, dict):
        raise SkymuleError(f"{source}: expected a JSON object, got {type(data).__name__}")
    try:
        summary = RunSummary.model_validate(data)
    except ValidationError as exc:
        raise SkymuleError(format_validation_error(source, exc)) from None
    if set(summary.per_sensor_buffer_mbit) != set(summary.per_sensor_downloaded_mbit):
        raise SkymuleError(
            f"{source}: per_sensor_buffer_mbit and per_sensor_downloaded_mbit name different "
            f"sensors ({', '.join(summary.per_sensor_buffer_mbit)} vs "
            f"{', '.join(summary.per_sensor_downloaded_mbit)})"
        )
    return data


def validate_scenario_json(data: Any, source: str, run_dir: Path) -> dict[str, Any]:
    """``scenario.json`` contents, checked against the scenario schema (returned unchanged).

    The ``policy`` table is left out of the check: the run's policy is recorded in
    ``summary.json``, and a replayed flight (``skymule analyze``) records a policy no scenario
    file can name (the flight's own download log).
    """
    if not isinstance(data, dict):
        raise SkymuleError(f"{source}: expected a JSON object, got {type(data).__name__}")
    scenario_from_dict({k: v for k, v in data.items() if k != "policy"}, source, run_dir)
    return data


FINITE_COLUMNS = ("t_s", "x_m", "y_m", "z_m", "rate_mbps", "downloaded_mbit", "distance_m")
"""slots.csv columns that must hold a finite number in every row."""
NON_NEGATIVE_COLUMNS = ("t_s", "rate_mbps", "downloaded_mbit", "distance_m")
OPTIONAL_NUMBER_COLUMNS = ("lat", "lon", "speed_mps", "power_w")
"""slots.csv columns that may be absent or empty but otherwise hold numbers."""
REQUIRED_COLUMNS = (*FINITE_COLUMNS, "served", "hovering")


def _cell_problem(path: str, column: str, index: int, raw: Any, allowed: str) -> SkymuleError:
    empty = raw is None or (isinstance(raw, float) and np.isnan(raw))
    shown = "an empty cell" if empty else repr(raw.item() if isinstance(raw, np.generic) else raw)
    return SkymuleError(
        f"{path}: data row {index + 1}, column {column!r}: {shown} is not allowed; "
        f"allowed: {allowed}"
    )


def _numbers(
    slots: pd.DataFrame, column: str, path: str, *, empty_ok: bool, inf_ok: bool
) -> np.ndarray:
    """The column as floats; the first cell that is not an allowed number is an error."""
    raw = slots[column]
    values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    empty = raw.isna().to_numpy(dtype=bool)
    bad = np.isnan(values) & ~empty
    if not empty_ok:
        bad |= empty
    if not inf_ok:
        bad |= np.isinf(values)
    allowed = "a finite number" if not inf_ok else "a number, inf or -inf"
    allowed += ", or empty" if empty_ok else ""
    if bad.any():
        index = int(np.argmax(bad))
        raise _cell_problem(path, column, index, raw.iloc[index], allowed)
    return values


def _check_column_set(slots: pd.DataFrame, summary: dict[str, Any], path: str) -> list[str]:
    missing = [c for c in REQUIRED_COLUMNS if c not in slots.columns]
    names = [c.removeprefix("snr_db_") for c in slots.columns if c.startswith("snr_db_")]
    if missing or not names:
        shown = missing or ["snr_db_<sensor>"]
        raise SkymuleError(
            f"{path}: missing column(s) {', '.join(shown)}; "
            "not written by `skymule run` (or damaged)"
        )
    expected = list(summary["per_sensor_downloaded_mbit"])
    if sorted(names) != sorted(expected):
        raise SkymuleError(
            f"{path}: sensor columns snr_db_{', snr_db_'.join(names)} do not match "
            f"summary.json's sensors {', '.join(expected)}; the files come from different runs"
        )
    return names


def check_slots(slots: pd.DataFrame, summary: dict[str, Any], path: str) -> pd.DataFrame:
    """The slot table, checked column by column and against ``summary.json``'s slot count.

    Returns the table with ``served`` as strings (empty: no sensor served).
    """
    names = _check_column_set(slots, summary, path)
    # several UAVs (docs/fleet.md): one row per UAV and slot, each UAV's rows in time order
    uavs = slots["uav"].astype(str) if "uav" in slots.columns else None
    n_uavs = 1 if uavs is None else max(uavs.nunique(), 1)
    expected_rows = int(summary["slots"]) * n_uavs
    if slots.empty:
        raise SkymuleError(
            f"{path}: header only, no slot rows (summary.json says slots = {expected_rows}); "
            "rewrite the run with `skymule run`"
        )
    if len(slots) != expected_rows:
        raise SkymuleError(
            f"{path}: {len(slots)} slot rows but summary.json says slots = {expected_rows}; "
            "the file is truncated or belongs to another run (rewrite it with `skymule run`)"
        )
    for column in FINITE_COLUMNS:
        values = _numbers(slots, column, path, empty_ok=False, inf_ok=False)
        if column in NON_NEGATIVE_COLUMNS and (values < 0).any():
            index = int(np.argmax(values < 0))
            raise _cell_problem(path, column, index, slots[column].iloc[index], "a number >= 0")
    for name in names:
        _numbers(slots, f"snr_db_{name}", path, empty_ok=True, inf_ok=True)
        column = f"remaining_mbit_{name}"
        if column in slots.columns:
            values = _numbers(slots, column, path, empty_ok=False, inf_ok=False)
            if (values < 0).any():
                index = int(np.argmax(values < 0))
                raise _cell_problem(path, column, index, slots[column].iloc[index], "a number >= 0")
    for column in OPTIONAL_NUMBER_COLUMNS:
        if column in slots.columns:
            _numbers(slots, column, path, empty_ok=True, inf_ok=False)
    hovering = _numbers(slots, "hovering", path, empty_ok=False, inf_ok=False)
    if not np.isin(hovering, (0.0, 1.0)).all():
        index = int(np.argmax(~np.isin(hovering, (0.0, 1.0))))
        raise _cell_problem(path, "hovering", index, slots["hovering"].iloc[index], "0 or 1")
    served = slots["served"].fillna("").astype(str)
    unknown = ~served.isin(["", *names]).to_numpy(dtype=bool)
    if unknown.any():
        index = int(np.argmax(unknown))
        raise _cell_problem(
            path, "served", index, served.iloc[index], f"empty or one of {', '.join(names)}"
        )
    t_s = slots["t_s"].to_numpy(dtype=float)
    groups = [np.arange(len(t_s))] if uavs is None else list(slots.groupby(uavs).indices.values())
    for rows in groups:
        later = np.diff(t_s[rows]) <= 0
        if later.any():
            index = int(rows[int(np.argmax(later)) + 1])
            raise _cell_problem(
                path, "t_s", index, t_s[index], "a time after the previous row's (increasing)"
            )
    return slots.assign(served=served)


MBIT_TOLERANCE = 1e-6
"""Slack [Mbit] (plus 1e-9 of the value) when sums of one run's numbers are compared:
slots.csv keeps 10 significant digits, summary.json every digit."""


def _differ(a: float, b: float) -> bool:
    return abs(a - b) > MBIT_TOLERANCE + 1e-9 * max(abs(a), abs(b))


def check_run_whole(
    summary: dict[str, Any], slots: pd.DataFrame, scenario: dict[str, Any], run_dir: Path
) -> None:
    """The files of one run folder, each valid on its own, checked against each other.

    ``summary.json``: ``total_downloaded_mbit`` (and ``total_buffer_mbit``) equal the sums of
    the per-sensor entries, and no sensor gave more than its buffer. ``slots.csv``: the
    downloads add up to the summary's total and, per served sensor, to its entry (all UAVs'
    rows of a fleet together: the buffers are shared). ``scenario.json`` (when present) lists
    the run's sensors. Raises the first mismatch as one line naming the files.
    """
    summary_path, slots_path = run_dir / "summary.json", run_dir / "slots.csv"
    again = "the files come from different runs or were edited; rewrite it with `skymule run`"
    down = {k: float(v) for k, v in summary["per_sensor_downloaded_mbit"].items()}
    buffers = {k: float(v) for k, v in summary["per_sensor_buffer_mbit"].items()}
    total = float(summary["total_downloaded_mbit"])
    if _differ(total, sum(down.values())):
        raise SkymuleError(
            f"{summary_path}: total_downloaded_mbit = {total:g} but per_sensor_downloaded_mbit "
            f"adds up to {sum(down.values()):g} Mbit; {again}"
        )
    if summary.get("total_buffer_mbit") is not None:
        total_buffer = float(summary["total_buffer_mbit"])
        if _differ(total_buffer, sum(buffers.values())):
            raise SkymuleError(
                f"{summary_path}: total_buffer_mbit = {total_buffer:g} but "
                f"per_sensor_buffer_mbit adds up to {sum(buffers.values()):g} Mbit; {again}"
            )
    for name, got in down.items():
        if got > buffers[name] and _differ(got, buffers[name]):
            raise SkymuleError(
                f"{summary_path}: sensor {name!r} gave {got:g} Mbit, more than its buffer of "
                f"{buffers[name]:g} Mbit (per_sensor_buffer_mbit); {again}"
            )
    downloaded = slots["downloaded_mbit"].to_numpy(float)
    if _differ(float(downloaded.sum()), total):
        raise SkymuleError(
            f"{slots_path}: column downloaded_mbit adds up to {downloaded.sum():g} Mbit but "
            f"summary.json says total_downloaded_mbit = {total:g}; {again}"
        )
    served = slots["served"].to_numpy(str)
    for name, got in down.items():
        in_slots = float(downloaded[served == name].sum())
        if _differ(in_slots, got):
            raise SkymuleError(
                f"{slots_path}: the slots serving {name!r} download {in_slots:g} Mbit but "
                f"summary.json says {got:g} (per_sensor_downloaded_mbit); {again}"
            )
    listed = [s.get("name") for s in scenario.get("sensors", []) if isinstance(s, dict)]
    if scenario and sorted(map(str, listed)) != sorted(down):
        raise SkymuleError(
            f"{run_dir / 'scenario.json'}: sensors {', '.join(map(str, listed))} do not match "
            f"the run's sensors {', '.join(down)} (slots.csv, summary.json); {again}"
        )
