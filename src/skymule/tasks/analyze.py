"""``skymule analyze LOG``: a recorded AERPAW/AADM flight, replayed and reported.

The merged log or digital-twin export (see :mod:`skymule.io.traces`; a DT export's X/Y are taken
as metres from the site origin, the AADM launch point for Lake Wheeler towers) becomes a
trace scenario: one sensor per SNR
column, buffers from an AADM volume file or ``--buffers`` (default: 1000 Mbit each, the
challenge's example). Greedy, HGAD (or any registered policies) then replay the same trace
through the engine (:func:`skymule.tasks.simulate.simulate`) and each writes a run folder; the
result is a compare folder that ``skymule report`` reads like any other.

When the flight's own download log is given, it becomes one more run folder, ``flight``:
what was really downloaded, when, from whom, on the recorded positions and SNRs.

Download log format (CSV, header required, column names case-insensitive)::

    time,tower,mbit
    2025-05-24 16:19:31.186,LW1,2.43
    2025-05-24 16:19:32.190,LW1,2.51

* ``time``: timestamp in the merged log's format (or plain seconds since the log's first
  sample; the only form for a digital-twin export); the row belongs to the slot that
  contains it.
* ``tower``: the sensor the data came from (a merged-log SNR column name, ``LW1`` or
  ``snr_lw1``).
* ``mbit``: data received in that row [Mbit], >= 0.

Several rows in one slot from the same tower add up; two towers in one slot is an error
(one tower a slot, as in the challenge). Downloads beyond a tower's buffer are clipped.

The AADM controller's own download log (``time,dl_lw1,...,dl_lwN``, cumulative Mbit per tower,
one row a poll; :mod:`skymule.aadm.files`) is read too, detected from its header: row k is
the k-th poll after the volumes were shared, i.e. trace slot (first row's slot) + k; rows
past the end of the merged log are left out of the flight run.

Scores (:mod:`skymule.aadm.score`, the rule in force): the flight is scored from its download
log as the controller did (t1 from the log's first row); each replayed policy from the slot
in which the recorded flight first climbed above 24 m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.aadm import files as aadm_files
from skymule.aadm.score import share_slot_from_altitude
from skymule.errors import SkymuleError
from skymule.geo import load_site
from skymule.io.runs import slots_frame, write_run
from skymule.io.traces import Trace, normalise_column, read_trace, read_volumes
from skymule.metrics.flights import NO_SENSOR, MissionLog, flight_record
from skymule.metrics.summary import summarize
from skymule.policies import check_policies
from skymule.rules.contract import served_bits
from skymule.rules.score import aadm_score_one
from skymule.scenario import Scenario, scenario_from_dict
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission, build_mission

#: Buffer per tower when neither a volume file nor --buffers is given [Mbit].
DEFAULT_BUFFER_MBIT = 1000.0
FLIGHT_RUN = "flight"
SITE = "lake-wheeler"


def parse_buffers(text: str, n_sensors: int) -> list[float]:
    """``--buffers``: one number for every sensor, or one per sensor, in Mbit."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = []
    if not values or any(not math.isfinite(v) or v < 0 for v in values):
        raise SkymuleError(
            f"--buffers {text!r}: expected non-negative Mbit values separated by commas"
        )
    if len(values) == 1:
        return values * n_sensors
    if len(values) != n_sensors:
        raise SkymuleError(
            f"--buffers {text!r}: {len(values)} values for {n_sensors} sensors; give one "
            "value for all or one per sensor"
        )
    return values


def resolve_buffers(trace: Trace, volumes: Path | None, buffers: str | None) -> list[float]:
    """Buffers [Mbit] per trace column from a volume file, --buffers or the default."""
    n_sensors = len(trace.columns)
    if volumes is not None and buffers is not None:
        raise SkymuleError("give either --volumes or --buffers, not both")
    if buffers is not None:
        return parse_buffers(buffers, n_sensors)
    if volumes is None:
        return [DEFAULT_BUFFER_MBIT] * n_sensors
    values = read_volumes(volumes)
    if len(values) != n_sensors:
        raise SkymuleError(
            f"{volumes}: {len(values)} volumes for {n_sensors} SNR columns "
            f"({', '.join(trace.columns)}) in the log; give one volume a line, in that order"
        )
    return [float(v) for v in values]


def _site_fields(trace: Trace) -> dict[str, Any]:
    """Lake Wheeler towers, fence and launch point when the log's columns are its towers."""
    site = load_site(SITE)
    towers = {p.name.upper(): p for p in site.towers}
    if all(c in towers for c in trace.columns):
        launch = site.launch
        return {
            "site": {"origin": {"lat": launch.lat_deg, "lon": launch.lon_deg}, "geofence": SITE},
            "positions": {
                c: {
                    "lat": towers[c].lat_deg,
                    "lon": towers[c].lon_deg,
                    "height_m": towers[c].antenna_height_m or 10.0,
                }
                for c in trace.columns
            },
        }
    if trace.lat_deg is not None and trace.lon_deg is not None:
        origin = {"lat": float(trace.lat_deg[0]), "lon": float(trace.lon_deg[0])}
        return {"site": {"origin": origin}, "positions": {}}
    return {"site": {}, "positions": {}}


def analysis_scenario(trace: Trace, log_path: Path, buffers_mbit: list[float]) -> Scenario:
    """The trace scenario a recorded flight is replayed under."""
    fields = _site_fields(trace)
    sensors = [
        {"name": name, "buffer_mbit": buffer, **fields["positions"].get(name, {})}
        for name, buffer in zip(trace.columns, buffers_mbit, strict=True)
    ]
    data = {
        "name": log_path.stem,
        "site": fields["site"],
        "sensors": sensors,
        "signal": {"source": "trace", "trace": str(log_path.resolve())},
        "trajectory": {"mode": "fixed"},
    }
    return scenario_from_dict(data, str(log_path), log_path.parent)


@dataclass(frozen=True)
class DownloadLog:
    """A flight's own downloads, per slot."""

    served: np.ndarray  # (T,) sensor index or NO_SENSOR
    downloaded_bit: np.ndarray  # (T,) as logged [bit]


def _log_start(log_path: Path) -> pd.Timestamp | None:
    head = pd.read_csv(log_path, nrows=1, dtype=str)
    column = next((c for c in head.columns if c.strip().lower() == "time"), None)
    if column is None or head.empty:
        return None
    if pd.notna(pd.to_numeric(head[column].iloc[0], errors="coerce")):
        return None  # seconds (digital-twin exports): no timestamp to anchor to
    try:
        return pd.Timestamp(head[column].iloc[0].strip())
    except ValueError:
        return None


def read_download_log(
    path: Path, log_path: Path, sensor_names: tuple[str, ...], n_slots: int, slot_s: float
) -> DownloadLog:
    """Parse the download log documented in this module (one-line errors)."""
    try:
        table = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, ValueError) as exc:
        raise SkymuleError(f"{path}: cannot read download log ({exc})") from None
    columns = {c.strip().lower(): c for c in table.columns}
    missing = [c for c in ("time", "tower", "mbit") if c not in columns]
    if missing:
        raise SkymuleError(
            f"{path}: missing column(s) {', '.join(missing)} (expected time,tower,mbit)"
        )
    times = table[columns["time"]].str.strip()
    numeric = pd.to_numeric(times, errors="coerce")
    if numeric.notna().all():
        offset_s = numeric.to_numpy(float)
    else:
        start = _log_start(log_path)
        stamps = pd.to_datetime(times, errors="coerce", format="mixed")
        bad = int(np.argmax(stamps.isna().to_numpy())) if stamps.isna().any() else -1
        if start is None or bad >= 0:
            row = bad + 2 if bad >= 0 else 2
            raise SkymuleError(
                f"{path}: row {row}, column time: {times.iloc[max(bad, 0)]!r} is not a "
                "timestamp like the merged log's (or seconds since its start)"
            )
        offset_s = (stamps - start).dt.total_seconds().to_numpy(float)
    mbit = pd.to_numeric(table[columns["mbit"]], errors="coerce").to_numpy(float)
    keys = {normalise_column(n): i for i, n in enumerate(sensor_names)}
    served = np.full(n_slots, NO_SENSOR, dtype=int)
    got = np.zeros(n_slots)
    for row, (t_s, tower, value) in enumerate(
        zip(offset_s, table[columns["tower"]], mbit, strict=True), start=2
    ):
        slot = math.floor(t_s / slot_s + 1e-9)
        where = f"{path}: row {row}"
        if not math.isfinite(value) or value < 0:
            raise SkymuleError(f"{where}, column mbit: not a non-negative number of Mbit")
        if normalise_column(tower) not in keys:
            raise SkymuleError(
                f"{where}, column tower: {tower!r} is not a log sensor "
                f"(allowed: {', '.join(sensor_names)})"
            )
        if not 0 <= slot < n_slots:
            raise SkymuleError(
                f"{where}, column time: {t_s:.1f} s is outside the flight (0 to "
                f"{n_slots * slot_s:g} s)"
            )
        index = keys[normalise_column(tower)]
        if served[slot] not in (NO_SENSOR, index):
            raise SkymuleError(
                f"{where}: two towers in the slot at {slot * slot_s:g} s "
                f"({sensor_names[served[slot]]} and {sensor_names[index]}); one tower a slot"
            )
        served[slot] = index
        got[slot] += value * BITS_PER_MBIT
    return DownloadLog(served=served, downloaded_bit=got)


@dataclass(frozen=True)
class ScoredDownloads:
    """A download log mapped onto the trace's slots, with the flight's AADM score parts."""

    downloads: DownloadLog
    score: dict[str, float | bool]


#: Mbit a logged total may exceed its tower's volume by (the controller logs 2 decimals).
LOG_VOLUME_SLACK_MBIT = 0.01


def check_download_totals(
    path: Path, log: aadm_files.AadmDownloadLog, volumes_mbit: np.ndarray
) -> None:
    """Refuse a download log in which a tower got more than its volume (the controller clips
    every tower at its volume: such a log is not of this flight, or not of these volumes)."""
    over = log.cumulative_mbit > volumes_mbit[None, :] + LOG_VOLUME_SLACK_MBIT
    if over.any():
        row, tower = (int(i) for i in np.argwhere(over)[0])
        raise SkymuleError(
            f"{path}: row {row + 2}, column {log.towers[tower]}: "
            f"{log.cumulative_mbit[row, tower]:g} Mbit downloaded, more than the tower's "
            f"volume of {volumes_mbit[tower]:g} Mbit; a tower can give at most its volume"
        )


def read_aadm_download_log(
    path: Path, log_path: Path, mission: Mission, share_slot: int
) -> ScoredDownloads:
    """The controller's ``time,dl_lw1,...`` log: one row a poll, scored as the controller did.

    Row k lands in trace slot s0 + k, s0 the slot of the first row's timestamp in the merged
    log (``share_slot`` for a log without timestamps).
    """
    log = aadm_files.read_download_log(path)
    names = mission.sensor_names
    if len(log.towers) != len(names):
        raise SkymuleError(
            f"{path}: {len(log.towers)} tower columns for the {len(names)} SNR columns "
            f"({', '.join(names)}) of {log_path.name}"
        )
    check_download_totals(path, log, mission.buffers_bit / BITS_PER_MBIT)
    steps_bit = np.diff(log.cumulative_mbit, axis=0, prepend=0.0) * BITS_PER_MBIT
    start = _log_start(log_path)
    first = share_slot
    if start is not None:
        first = math.floor((pd.Timestamp(log.start) - start).total_seconds() / mission.slot_s)
    if not 0 <= first < mission.n_slots:
        raise SkymuleError(
            f"{path}: the first row ({log.start}) is outside the flight in {log_path.name}"
        )
    served = np.full(mission.n_slots, NO_SENSOR, dtype=int)
    got = np.zeros(mission.n_slots)
    rows = min(len(steps_bit), mission.n_slots - first)
    per_row = steps_bit[:rows]
    active = per_row.sum(axis=1) > 0
    served[first : first + rows] = np.where(active, per_row.argmax(axis=1), NO_SENSOR)
    got[first : first + rows] = per_row.sum(axis=1)
    score = aadm_score_one(steps_bit.sum(axis=1), float(mission.buffers_bit.sum()), 1.0)
    return ScoredDownloads(DownloadLog(served=served, downloaded_bit=got), score)


def flight_log(mission: Mission, downloads: DownloadLog) -> MissionLog:
    """A MissionLog of what the flight really did (positions/SNR from the trace)."""
    assert mission.track is not None
    track = mission.track
    n_slots = min(mission.n_slots, track.n_samples)
    served = downloads.served[:n_slots]
    remaining = np.empty((n_slots, mission.n_sensors))
    downloaded = np.zeros(n_slots)
    left = mission.buffers_bit.astype(float).copy()
    for t in range(n_slots):
        if served[t] != NO_SENSOR:
            # y = min(R dt, Q), the logged bits standing for R dt
            downloaded[t] = served_bits(downloads.downloaded_bit[t], left[served[t]], 1.0)
            left[served[t]] -= downloaded[t]
        remaining[t] = left
    positions = track.position_m[:n_slots]
    return MissionLog(
        flight_record(
            policy=FLIGHT_RUN,
            sensor_names=mission.sensor_names,
            slot_s=mission.slot_s,
            buffers_bit=mission.buffers_bit,
            position_m=positions,
            end_position_m=positions[-1],
            snr_db=track.snr_db[:n_slots],
            rate_bps=mission.rate_bps(track.snr_db[:n_slots]),
            served=served,
            downloaded_bit=downloaded,
            remaining_bit=remaining,
            hovering=np.zeros(n_slots, bool),
            home_m=np.zeros(2),
        )
    )


def analyze_flight(
    log_path: Path,
    out_dir: Path,
    *,
    policies: list[str],
    volumes: Path | None = None,
    buffers: str | None = None,
    download_log: Path | None = None,
) -> list[dict[str, Any]]:
    """Replay a recorded flight under ``policies`` into the compare folder ``out_dir``.

    Returns the comparison rows (one per run folder written).
    """
    from skymule.tasks.compare import compare_policies, comparison_row, write_compare

    check_policies(list(policies))
    trace = read_trace(log_path)
    buffers_mbit = resolve_buffers(trace, volumes, buffers)
    scenario = analysis_scenario(trace, log_path, buffers_mbit)
    mission = build_mission(scenario)
    assert mission.track is not None
    share = share_slot_from_altitude(mission.track.position_m[: mission.n_slots, 2])
    total_bit = float(mission.buffers_bit.sum())
    replayed = compare_policies(scenario, policies, bound=False, mission=mission)
    comparison = replayed.with_summaries(
        lambda run: aadm_score_one(
            run.result.log.downloaded_bit, total_bit, mission.slot_s, share_slot=share
        )
    )
    extra = []
    if download_log is not None:
        if aadm_files.is_aadm_download_log(download_log):
            scored = read_aadm_download_log(download_log, log_path, mission, share)
            downloads, parts = scored.downloads, scored.score
        else:
            downloads = read_download_log(
                download_log, log_path, mission.sensor_names, mission.n_slots, mission.slot_s
            )
            parts = {}
        log = flight_log(mission, downloads)
        if not parts:
            parts = aadm_score_one(log.downloaded_bit, total_bit, mission.slot_s, share_slot=share)
        summary = {**summarize(log, scenario.name), **parts}
        scenario_dict = scenario.to_toml_dict()
        scenario_dict["policy"] = {"name": FLIGHT_RUN, "download_log": str(download_log)}
        write_run(out_dir / FLIGHT_RUN, summary, slots_frame(log, mission.frame), scenario_dict)
        extra.append(comparison_row(summary))
    write_compare(comparison, out_dir, extra)
    return [*comparison.rows(), *extra]
