"""``skymule sim2real``: how wrong a twin's numbers are on a real flight, SNR and policies.

The question a user of a digital twin (DT) has: if I trust this twin, how wrong will my
policy's numbers be on the real flight? For each twin, on the real flight's own samples:

* SNR: the twin's prediction at every recorded position against what was measured, per
  sensor: RMSE, bias (predicted - measured) and MAE [dB], and the rate's RMSE and bias
  [Mbit/s] (:func:`skymule.radio.radiomap.score_source`; missing samples and deep drops left
  out). Where the twin gives a predictive sigma (every fitted map does), the share of
  measurements inside the twin's 95% interval (prediction +- 1.96 sigma).
* Policies: what each policy downloads replaying the real flight (its recorded SNR, slot by
  slot) against what it downloads flying the *same recorded path* under the twin
  (``[trajectory] flight``), and the relative error (twin - real) / real.

Both missions are the scenario's (sensors, buffers, link budget, rate table, policy
parameters) on the real flight's time line: slot k starts k slot_s after the flight's first
sample (the replay holds each recorded sample until the next, the twin flies the recorded
positions interpolated in time), and the mission lasts as long as the flight.

A twin is a radio-map JSON (``fit-radiomap --out``; learned twins too), a recorded flight
(``.csv``: a DT export or a merged log, fitted to a kriging map on the fly) or a scenario or
preset (its ``[radio]`` and ``[signal]``: a model source as the scenario simulates it).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.io.textfiles import json_safe
from skymule.scenario import Scenario, load_scenario
from skymule.tasks.radiomaps import is_map_file, is_trace_file

RESULT_JSON = "sim2real.json"
SAMPLES_CSV = "sim2real_snr.csv"
COVERAGE_Z = 1.959964
"""Two-sided 95% normal quantile: the twin's interval is prediction +- COVERAGE_Z sigma."""


@dataclass(frozen=True)
class TwinResult:
    """One twin scored against the real flight."""

    twin: str
    scores: dict[str, dict[str, float]]
    policies: dict[str, dict[str, float | None]]
    coverage: dict[str, float] | None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"twin": self.twin, **self.scores, "policies": self.policies}
        if self.coverage is not None:
            out["coverage_95"] = self.coverage
        return out


@dataclass(frozen=True)
class Sim2Real:
    """Every twin against one real flight, and the samples the figures are drawn from.

    ``samples`` is long: one row per (twin, sensor, recorded sample) with ``time_s``,
    ``measured_db``, ``predicted_db`` and ``sigma_db`` (NaN where the twin gives none).
    """

    scenario: str
    real: str
    real_mbit: dict[str, float]
    twins: tuple[TwinResult, ...]
    samples: pd.DataFrame

    def to_json(self) -> dict[str, Any]:
        """The ``--json`` document: ``{"twins": [...]}`` plus what was compared."""
        return {
            "scenario": self.scenario,
            "real": self.real,
            "real_mbit": self.real_mbit,
            "twins": [t.to_json() for t in self.twins],
        }


def relative_error(real: float, twin: float) -> float | None:
    """(twin - real) / real, or None when the real flight downloaded nothing."""
    return (twin - real) / real if real > 0 else None


def _flown(base: Scenario, real: Path) -> Scenario:
    """``base`` on the real flight's time line: fixed, as long as the flight, time-based slots."""
    mission = base.mission.model_copy(update={"duration_s": None, "slot_s": base.mission.slot_s})
    trajectory = base.trajectory.model_copy(update={"mode": "fixed", "waypoints": None})
    return base.model_copy(update={"mission": mission, "trajectory": trajectory, "uavs": None})


def real_variant(base: Scenario, real: Path) -> Scenario:
    """The real flight replayed: its recorded SNR slot by slot (sample-and-hold in time),
    without the scenario's simulated fading (a recorded SNR has its own)."""
    flown = _flown(base, real)
    signal = flown.signal.model_copy(
        update={"source": "trace", "trace": str(real.resolve()), "map": None, "traces": None}
    )
    trajectory = flown.trajectory.model_copy(update={"flight": None})
    radio = flown.radio.model_copy(update={"fading": "none"})
    return flown.model_copy(update={"signal": signal, "trajectory": trajectory, "radio": radio})


def twin_variant(base: Scenario, real: Path, twin: str) -> Scenario:
    """The real flight's path flown under ``twin`` (a map, a flight or a scenario/preset)."""
    flown = _flown(base, real)
    trajectory = flown.trajectory.model_copy(update={"flight": str(real.resolve())})
    update: dict[str, Any] = {"trace": None, "map": None, "traces": None}
    radio = flown.radio
    if is_map_file(twin):
        update |= {"source": "radiomap", "map": str(Path(twin).resolve())}
    elif is_trace_file(twin):
        update |= {"source": "radiomap", "traces": [str(Path(twin).resolve())]}
    else:
        other = load_scenario(twin)
        signal = other.signal
        if signal.source == "trace":
            raise SkymuleError(
                f"--twin {twin}: signal.source = 'trace' replays a flight and predicts nothing "
                "elsewhere; pass the flight itself (.csv) to fit a map to it"
            )
        radio = other.radio
        update["source"] = signal.source
        if signal.map:
            update["map"] = str(other.resolve_path(signal.map).resolve())
        if signal.traces:
            update["traces"] = [str(other.resolve_path(p).resolve()) for p in signal.traces]
    signal = flown.signal.model_copy(update=update)
    return flown.model_copy(update={"signal": signal, "trajectory": trajectory, "radio": radio})


def _mbit(scenario: Scenario, policies: Sequence[str]) -> dict[str, float]:
    from skymule.tasks.compare import compare_policies

    comparison = compare_policies(scenario, policies, bound=False)
    return {
        run.policy: float(run.result.summary["total_downloaded_mbit"]) for run in comparison.runs
    }


def sim2real(
    scenario: str | Scenario, real_trace: Path, twins: Sequence[str], policies: Sequence[str]
) -> Sim2Real:
    """Score every twin against the real flight ``real_trace`` (see the module docstring)."""
    from skymule.io.traces import TraceError, positions_local, read_trace
    from skymule.policies import check_policies
    from skymule.radio.radiomap import score_source
    from skymule.world import build_mission

    if not twins:
        raise SkymuleError("sim2real: give at least one --twin (a map .json, a flight .csv or a "
                           "scenario)")  # fmt: skip
    names = check_policies(list(policies))
    base = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    label = str(scenario) if not isinstance(scenario, Scenario) else scenario.name
    real = build_mission(real_variant(base, real_trace))
    sensors = base.signal.sensors_from_trace or [s.name for s in base.sensors]
    try:
        recorded = read_trace(real_trace, sensors=sensors)
    except TraceError as exc:
        raise SkymuleError(str(exc)) from None
    real_mbit = _mbit(real.scenario, names)
    results, frames = [], []
    for twin in twins:
        variant = twin_variant(base, real_trace, twin)
        mission = build_mission(variant)
        assert mission.source is not None
        positions = positions_local(recorded, mission.frame.to_local)
        predicted = np.asarray(mission.source.snr_db(positions), float)
        scores = score_source(predicted, recorded.snr_db, mission.sensor_names, mission.rate_bps)
        sigma_of = getattr(mission.source, "sigma_db", None)
        sigma = None if sigma_of is None else np.asarray(sigma_of(positions), float)
        coverage = None
        if sigma is not None:
            coverage = _coverage(predicted, sigma, recorded.snr_db, mission.sensor_names)
        twin_mbit = _mbit(variant, names)
        results.append(
            TwinResult(
                twin=twin,
                scores=scores,
                policies={
                    p: {
                        "real_mbit": real_mbit[p],
                        "twin_mbit": twin_mbit[p],
                        "error": relative_error(real_mbit[p], twin_mbit[p]),
                    }
                    for p in names
                },
                coverage=coverage,
            )
        )
        frames.append(
            _samples(twin, recorded.time_s, recorded.snr_db, predicted, sigma, mission.sensor_names)
        )
    return Sim2Real(label, str(real_trace), real_mbit, tuple(results), pd.concat(frames))


def _coverage(
    predicted: np.ndarray, sigma: np.ndarray, measured: np.ndarray, names: Sequence[str]
) -> dict[str, float]:
    """Per sensor: share of valid measurements within prediction +- COVERAGE_Z sigma."""
    from skymule.radio.radiomap import DEEP_DROP_DB, valid_mask

    out = {}
    for j, name in enumerate(names):
        ok, _, _ = valid_mask(measured[:, j], DEEP_DROP_DB)
        inside = np.abs(predicted[ok, j] - measured[ok, j]) <= COVERAGE_Z * sigma[ok, j]
        out[name] = float(inside.mean()) if inside.size else math.nan
    return out


def _samples(
    twin: str,
    time_s: np.ndarray,
    measured: np.ndarray,
    predicted: np.ndarray,
    sigma: np.ndarray | None,
    names: Sequence[str],
) -> pd.DataFrame:
    n = len(time_s)
    return pd.DataFrame(
        {
            "twin": np.repeat(twin, n * len(names)),
            "sensor": np.repeat(np.asarray(names), n),
            "time_s": np.tile(time_s, len(names)),
            "measured_db": measured.T.ravel(),
            "predicted_db": predicted.T.ravel(),
            "sigma_db": np.full(n * len(names), np.nan) if sigma is None else sigma.T.ravel(),
        }
    )


def write_sim2real(result: Sim2Real, out: Path) -> list[Path]:
    """Write ``out/sim2real.json`` and ``out/sim2real_snr.csv`` (atomically); their paths."""
    from skymule.io import atomic

    out.mkdir(parents=True, exist_ok=True)
    document = out / RESULT_JSON
    samples = out / SAMPLES_CSV
    atomic.write_text(samples, result.samples.to_csv(index=False, float_format="%.6g"))
    text = json.dumps(json_safe(result.to_json()), indent=2, allow_nan=False)
    atomic.write_text(document, text + "\n")
    return [document, samples]


def policy_rows(result: Sim2Real) -> list[dict[str, Any]]:
    """One row per (twin, policy): real and twin Mbit and the relative error."""
    return [{"twin": t.twin, "policy": p, **v} for t in result.twins for p, v in t.policies.items()]


def snr_rows(result: Sim2Real) -> list[dict[str, Any]]:
    """One row per (twin, sensor): the SNR and rate scores."""
    rows = []
    for t in result.twins:
        for sensor in t.scores["rmse_db"]:
            row: dict[str, Any] = {"twin": t.twin, "sensor": sensor}
            row |= {key: values[sensor] for key, values in t.scores.items()}
            if t.coverage is not None:
                row["coverage_95"] = t.coverage[sensor]
            rows.append(row)
    return rows


__all__ = [
    "RESULT_JSON",
    "SAMPLES_CSV",
    "Sim2Real",
    "TwinResult",
    "policy_rows",
    "sim2real",
    "snr_rows",
    "write_sim2real",
]
