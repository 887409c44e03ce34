"""``skymule sim2real``: which twin to trust on a real flight, with confidence intervals.

The question a user of a digital twin (DT) has: if I trust this twin, how wrong will my
numbers be on the real flight, and which of my twins should I trust? For each twin, on the
real flight's own samples (missing samples and deep drops left out):

* **SNR per tower**: RMSE, bias (predicted - measured) and MAE [dB], the rate's RMSE and bias
  [Mbit/s] per tower and for the best link (the largest rate over the towers, what a
  serving decision sees), and, where the twin gives a sigma, the share of measurements inside
  its 95% interval. Every number has a 90% moving-block bootstrap interval
  (:mod:`skymule.metrics.sim2real`; blocks of consecutive samples, a seeded Generator).
* **Reference rows** in the same table, labelled as references (yardsticks, not twins): the
  trace's noise floor (the residual from a running median of a few samples: what no smooth map
  predicts), free space (the scenario's link budget), log-distance fitted on the calibration
  set (``calibration``; without one, on the twins' recorded flights, and the notes say so) and
  an oracle log-distance refitted on the scored samples themselves.
* **Three policy-level numbers** per policy and twin, each with a 90% block-bootstrap interval
  over slots:

  a. *same-decisions error*: the serving decisions (the real flight's own, from its download
     log, else the policy's on the real trace) executed on the twin's rates and on the real
     ones, at the same slots and samples: (twin - real) / real Mbit. It isolates the rate
     model's error.
  b. *decision regret*: the policy decides on the twin; those decisions (serve, hover) are
     executed on the real trace and compared with the policy run on the real trace:
     (real policy - executed) / real policy Mbit. It is what trusting the twin costs.
  c. *own error*: the policy's Mbit on the twin against its Mbit on the trace, only where the
     two follow the recorded path with its timing. A policy that hovers freezes the trace's
     sample index, so after its first hover the two sides are at other places; then the
     number is left out (None) and the hover slots and the last sample reached on each side
     are given instead.

* **Ranking**: twins in increasing order of decision regret (the mean over the policies), and
  one line naming the twin to trust and why.

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skymule.errors import SkymuleError
from skymule.metrics.sim2real import (
    DEFAULT_BOOTSTRAP,
    NOISE_WINDOW,
    Bootstrap,
    Estimate,
    block_bootstrap,
    coverage,
    execute,
    fit_log_distance,
    on_path_slots,
    own_error_defined,
    rank_by,
    rate_errors,
    regret,
    relative_change,
    running_median,
    snr_errors,
)
from skymule.scenario import Scenario, load_scenario
from skymule.tasks.radiomaps import is_map_file, is_trace_file
from skymule.units import BITS_PER_MBIT

RESULT_JSON = "sim2real.json"
SAMPLES_CSV = "sim2real_snr.csv"
BEST_LINK = "best link"
"""The row of the rate scores of the largest rate over the towers."""
RECORDED = "recorded"
POLICY_ON_REAL = "policy on the real trace"
SNR_METRICS = ("rmse_db", "bias_db", "mae_db")
RATE_METRICS = ("rate_rmse_mbps", "rate_bias_mbps")


def _ci(estimate: Estimate) -> list[float]:
    return [estimate.low, estimate.high]


def _value(estimate: Estimate | None) -> float | None:
    return None if estimate is None else estimate.value


@dataclass(frozen=True)
class Scores:
    """One row group of the SNR table: a twin's or a reference's scores.

    ``towers`` maps a tower to its metrics (:data:`SNR_METRICS`, :data:`RATE_METRICS` and
    ``coverage_95`` where there is a sigma); ``best_link`` holds the rate metrics of the best
    link; ``counts`` the samples scored, missing and dropped per tower.
    """

    towers: dict[str, dict[str, Estimate]]
    best_link: dict[str, Estimate]
    counts: dict[str, dict[str, int]]

    def to_json(self) -> dict[str, Any]:
        """Today's flat fields (``rmse_db: {tower: x}``, ...) plus ``ci`` and ``best_link``."""
        metrics = list(dict.fromkeys(m for row in self.towers.values() for m in row))
        flat: dict[str, Any] = {
            m: {t: row[m].value for t, row in self.towers.items() if m in row}
            for m in metrics
            if m != "coverage_95"
        }
        flat |= self.counts
        flat["ci"] = {
            m: {t: _ci(row[m]) for t, row in self.towers.items() if m in row} for m in metrics
        }
        flat["best_link"] = {m: e.value for m, e in self.best_link.items()}
        flat["best_link"]["ci"] = {m: _ci(e) for m, e in self.best_link.items()}
        if any("coverage_95" in row for row in self.towers.values()):
            flat["coverage_95"] = {t: row["coverage_95"].value for t, row in self.towers.items()}
        return flat


@dataclass(frozen=True)
class PolicyNumbers:
    """One policy under one twin: the three policy-level numbers and what they come from.

    Fractions (multiply by 100 for %); Mbit totals; samples are 0-based track indices.
    """

    real_mbit: float
    twin_mbit: float
    decisions: str
    same_real_mbit: float
    same_twin_mbit: float
    same_decisions_error: Estimate
    executed_mbit: float
    regret: Estimate
    own_error: Estimate | None
    on_path_slots: int
    own_error_on_path: Estimate | None
    hover_slots_real: int
    hover_slots_twin: int
    last_sample_real: int
    last_sample_twin: int
    n_samples: int
    executed_bit: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    best_bit: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    @property
    def own_error_note(self) -> str | None:
        """Why there is no own error (None where there is one)."""
        if self.own_error is not None:
            return None
        return (
            f"hovers ({self.hover_slots_real} slots on the real trace, {self.hover_slots_twin} "
            f"on the twin, the first after slot {self.on_path_slots - 1}): a hover freezes the "
            f"trace's sample index, so after it the two sides are where the recorded flight was "
            f"not; last sample reached "
            f"{self.last_sample_real} (real) and {self.last_sample_twin} (twin) of "
            f"{self.n_samples}"
        )

    def to_json(self) -> dict[str, Any]:
        error = relative_error(self.real_mbit, self.twin_mbit)
        return {
            "real_mbit": self.real_mbit,
            "twin_mbit": self.twin_mbit,
            "error": error,
            "decisions": self.decisions,
            "same_decisions_error": self.same_decisions_error.value,
            "same_decisions_error_ci": _ci(self.same_decisions_error),
            "same_decisions_real_mbit": self.same_real_mbit,
            "same_decisions_twin_mbit": self.same_twin_mbit,
            "regret": self.regret.value,
            "regret_ci": _ci(self.regret),
            "executed_mbit": self.executed_mbit,
            "own_error": None if self.own_error is None else self.own_error.value,
            "own_error_ci": None if self.own_error is None else _ci(self.own_error),
            "own_error_note": self.own_error_note,
            "on_path_slots": self.on_path_slots,
            "own_error_on_path": _value(self.own_error_on_path),
            "own_error_on_path_ci": None
            if self.own_error_on_path is None
            else _ci(self.own_error_on_path),
            "hover_slots_real": self.hover_slots_real,
            "hover_slots_twin": self.hover_slots_twin,
            "last_sample_real": self.last_sample_real,
            "last_sample_twin": self.last_sample_twin,
            "n_samples": self.n_samples,
        }


@dataclass(frozen=True)
class TwinResult:
    """One twin scored against the real flight: its scores and its policy-level numbers.

    ``scores``, ``coverage`` and ``policies`` read as before (plain dicts: per metric per
    tower, per tower, per policy), ``metrics`` and ``numbers`` hold the estimates with their
    intervals.
    """

    twin: str
    metrics: Scores
    numbers: dict[str, PolicyNumbers]

    @property
    def scores(self) -> dict[str, dict[str, float]]:
        """Per metric (``rmse_db``, ``bias_db``, ...), per tower: the value."""
        document = self.metrics.to_json()
        return {k: v for k, v in document.items() if k not in ("ci", "best_link", "coverage_95")}

    @property
    def coverage(self) -> dict[str, float] | None:
        """Per tower: the share inside the twin's 95% interval, or None (no sigma)."""
        document = self.metrics.to_json()
        return document.get("coverage_95")

    @property
    def policies(self) -> dict[str, dict[str, Any]]:
        """Per policy: the JSON fields (``real_mbit``, ``twin_mbit``, ``error``, ...)."""
        return {p: v.to_json() for p, v in self.numbers.items()}

    def to_json(self) -> dict[str, Any]:
        return {"twin": self.twin, **self.metrics.to_json(), "policies": self.policies}


@dataclass(frozen=True)
class Reference:
    """A reference row group (a yardstick, not a twin): its label and how it was made."""

    reference: str
    fitted_on: str
    scores: Scores

    def to_json(self) -> dict[str, Any]:
        return {"reference": self.reference, "fitted_on": self.fitted_on} | self.scores.to_json()


@dataclass(frozen=True)
class Ranked:
    """A twin's place: its mean decision regret over the policies (with its interval)."""

    twin: str
    regret: Estimate
    same_decisions_error: float
    rmse_db: float

    def to_json(self) -> dict[str, Any]:
        return {
            "twin": self.twin,
            "regret": self.regret.value,
            "regret_ci": _ci(self.regret),
            "same_decisions_error": self.same_decisions_error,
            "rmse_db": self.rmse_db,
        }


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
    references: tuple[Reference, ...] = ()
    ranking: tuple[Ranked, ...] = ()
    boot: Bootstrap = DEFAULT_BOOTSTRAP
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def trust(self) -> str:
        """The one line naming the twin to trust and why."""
        return trust_line(self.ranking, list(self.real_mbit), self.boot.level)

    def to_json(self) -> dict[str, Any]:
        """The ``--json`` document: today's fields plus references, ranking and notes."""
        return {
            "scenario": self.scenario,
            "real": self.real,
            "real_mbit": self.real_mbit,
            "twins": [t.to_json() for t in self.twins],
            "references": [r.to_json() for r in self.references],
            "ranking": [r.to_json() for r in self.ranking],
            "trust": self.trust,
            "bootstrap": self.boot.to_json(),
            "noise_window": NOISE_WINDOW,
            "notes": list(self.notes),
        }


def relative_error(real: float, twin: float) -> float | None:
    """(twin - real) / real, or None when the real flight downloaded nothing."""
    return (twin - real) / real if real > 0 else None


def trust_line(ranking: Sequence[Ranked], policies: Sequence[str], level: float) -> str:
    """``trust X: ...``: the first twin of ``ranking`` and why (or why none)."""
    if not ranking:
        return "no twin to rank"
    best = ranking[0]
    over = " and ".join(policies)
    if not math.isfinite(best.regret.value):
        return f"no twin to trust: the policies ({over}) download nothing on the real flight"
    percent = 100.0 * best.regret.value
    line = (
        f"trust {best.twin}: its decisions cost {percent:.1f}% of what {over} download on the "
        f"real flight ({100 * level:.0f}% CI {100 * best.regret.low:.1f} to "
        f"{100 * best.regret.high:.1f}%), the least of {len(ranking)} twin"
        f"{'s' if len(ranking) != 1 else ''}"
    )
    if len(ranking) > 1:
        second = ranking[1]
        if second.regret.value <= best.regret.high and math.isfinite(second.regret.value):
            line += (
                f"; {second.twin} ({100 * second.regret.value:.1f}%) is inside that interval: "
                "this flight does not tell the two apart"
            )
        else:
            line += f"; next {second.twin} at {100 * second.regret.value:.1f}%"
    return line


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


def _runs(scenario: Scenario, policies: Sequence[str], mission: Any) -> dict[str, Any]:
    """Each policy's RunResult on ``scenario`` built as ``mission`` (identical draws)."""
    from skymule.tasks.compare import compare_policies

    comparison = compare_policies(scenario, policies, bound=False, mission=mission)
    return {run.policy: run.result for run in comparison.runs}


def _track_rates(result: Any) -> np.ndarray:
    """(K, N) rate at each track sample of a run's mission, without per-slot fading [bit/s]."""
    mission = result.mission
    assert mission.track is not None
    return np.asarray(mission.rate_bps(mission.track.snr_db), float)


@dataclass(frozen=True)
class _Decisions:
    """Serving decisions on a track: (T,) sample index, (T,) served sensor, their origin."""

    sample: np.ndarray
    served: np.ndarray
    origin: str


def _decisions_of(result: Any) -> _Decisions:
    log = result.log
    sample = np.asarray(log.flights.sample[log.index, : log.n_slots], np.int64)
    return _Decisions(sample, np.asarray(log.served, np.int64), POLICY_ON_REAL)


def _recorded_decisions(path: Path, real_trace: Path, mission: Any) -> _Decisions:
    """The real flight's own decisions from its download log (either format ``analyze``
    reads), at slot k on sample k: the recorded path with the recorded timing."""
    from skymule.aadm import files as aadm_files
    from skymule.tasks.analyze import read_aadm_download_log, read_download_log

    if not path.is_file():
        raise SkymuleError(f"--download-log {path}: no such file")
    if aadm_files.is_aadm_download_log(path):
        served = read_aadm_download_log(path, real_trace, mission, 0).downloads.served
    else:
        served = read_download_log(
            path, real_trace, mission.sensor_names, mission.n_slots, mission.slot_s
        ).served
    served = np.asarray(served, np.int64)
    return _Decisions(np.arange(served.size, dtype=np.int64), served, RECORDED)


def policy_numbers(
    real_run: Any,
    twin_run: Any,
    same: _Decisions,
    real_rates: np.ndarray,
    twin_rates: np.ndarray,
    boot: Bootstrap,
) -> PolicyNumbers:
    """The three policy-level numbers of one policy under one twin (module docstring)."""
    buffers, slot_s = real_run.mission.buffers_bit, real_run.mission.slot_s
    same_real = execute(real_rates, same.sample, same.served, buffers, slot_s)
    same_twin = execute(twin_rates, same.sample, same.served, buffers, slot_s)
    on_twin = _decisions_of(twin_run)
    executed = execute(real_rates, on_twin.sample, on_twin.served, buffers, slot_s)
    best = np.asarray(real_run.log.downloaded_bit, float)
    executed, best = _pad(executed, best)
    twin_bits, real_bits = _pad(np.asarray(twin_run.log.downloaded_bit, float), best)
    hover_real, hover_twin = real_run.log.hovering, twin_run.log.hovering
    own = None
    if own_error_defined(hover_real, hover_twin):
        own = relative_change(twin_bits, real_bits, boot)
    on_path = on_path_slots(hover_real, hover_twin)
    own_on_path = None
    if own is None and on_path >= 2:
        own_on_path = relative_change(twin_bits[:on_path], real_bits[:on_path], boot)
    real_samples = _decisions_of(real_run).sample
    return PolicyNumbers(
        real_mbit=float(real_run.summary["total_downloaded_mbit"]),
        twin_mbit=float(twin_run.summary["total_downloaded_mbit"]),
        decisions=same.origin,
        same_real_mbit=float(same_real.sum()) / BITS_PER_MBIT,
        same_twin_mbit=float(same_twin.sum()) / BITS_PER_MBIT,
        same_decisions_error=relative_change(same_twin, same_real, boot),
        executed_mbit=float(executed.sum()) / BITS_PER_MBIT,
        regret=regret(executed, best, boot),
        own_error=own,
        on_path_slots=on_path,
        own_error_on_path=own_on_path,
        hover_slots_real=int(np.sum(hover_real)),
        hover_slots_twin=int(np.sum(hover_twin)),
        last_sample_real=int(real_samples[-1]) if real_samples.size else 0,
        last_sample_twin=int(on_twin.sample[-1]) if on_twin.sample.size else 0,
        n_samples=int(real_rates.shape[0]),
        executed_bit=executed,
        best_bit=best,
    )


def _pad(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two per-slot series of bits zero-padded to one length (a run that ended early
    downloads nothing after its end)."""
    n = max(a.size, b.size)
    return np.pad(a, (0, n - a.size)), np.pad(b, (0, n - b.size))


def score_predictions(
    predicted_db: np.ndarray,
    measured_db: np.ndarray,
    names: Sequence[str],
    rate_bps: Any,
    boot: Bootstrap,
    sigma_db: np.ndarray | None = None,
) -> Scores:
    """Scores of predictions (S, N) against measurements (S, N) in time order (NaN in a
    prediction: not predicted there, left out)."""
    from skymule.radio.radiomap import DEEP_DROP_DB, valid_mask

    towers: dict[str, dict[str, Estimate]] = {}
    counts: dict[str, dict[str, int]] = {"n_scored": {}, "n_missing": {}, "n_deep_drops": {}}
    for j, name in enumerate(names):
        ok, missing, deep = valid_mask(measured_db[:, j], DEEP_DROP_DB)
        ok &= np.isfinite(predicted_db[:, j])
        guess, seen = predicted_db[ok, j], measured_db[ok, j]
        row = snr_errors(guess, seen, boot)
        row |= rate_errors(rate_bps(guess), rate_bps(seen), boot)
        if sigma_db is not None:
            row["coverage_95"] = coverage(guess, sigma_db[ok, j], seen, boot)
        towers[name] = row
        counts["n_scored"][name] = int(ok.sum())
        counts["n_missing"][name] = missing
        counts["n_deep_drops"][name] = deep
    best_guess = np.max(np.where(np.isfinite(predicted_db), rate_bps(predicted_db), 0.0), axis=1)
    best_seen = np.max(rate_bps(measured_db), axis=1)
    return Scores(towers, rate_errors(best_guess, best_seen, boot), counts)


def _noise_floor(measured_db: np.ndarray) -> np.ndarray:
    """(S, N) each tower's running median over its valid samples (NaN elsewhere)."""
    from skymule.radio.radiomap import DEEP_DROP_DB, valid_mask

    out = np.full(measured_db.shape, np.nan)
    for j in range(measured_db.shape[1]):
        ok, _, _ = valid_mask(measured_db[:, j], DEEP_DROP_DB)
        if ok.any():
            out[ok, j] = running_median(measured_db[ok, j], NOISE_WINDOW)
    return out


def _log_distance(
    fit_positions: np.ndarray,
    fit_snr: np.ndarray,
    sensor_m: np.ndarray,
    positions: np.ndarray,
) -> np.ndarray:
    """(S, N) log-distance fitted per tower on (fit_positions, fit_snr), at ``positions``."""
    from skymule.radio.radiomap import DEEP_DROP_DB, valid_mask

    out = np.full((positions.shape[0], sensor_m.shape[0]), np.nan)
    for j, tower in enumerate(sensor_m):
        ok, _, _ = valid_mask(fit_snr[:, j], DEEP_DROP_DB)
        if not ok.any():
            continue
        fitted = fit_log_distance(np.linalg.norm(fit_positions[ok] - tower, axis=1),
                                  fit_snr[ok, j])  # fmt: skip
        out[:, j] = fitted.snr_db(np.linalg.norm(positions - tower, axis=1))
    return out


def _free_space(base: Scenario, real: Path, positions: np.ndarray) -> np.ndarray:
    """(S, N) the scenario's link budget in free space (no shadowing, no fading)."""
    from skymule.world import build_mission

    flown = _flown(base, real)
    radio = flown.radio.model_copy(
        update={"model": "fspl", "params": {}, "shadowing_std_db": 0.0, "fading": "none"}
    )
    signal = flown.signal.model_copy(
        update={"source": "model", "trace": None, "map": None, "traces": None}
    )
    trajectory = flown.trajectory.model_copy(update={"flight": str(real.resolve())})
    variant = flown.model_copy(update={"radio": radio, "signal": signal, "trajectory": trajectory})
    mission = build_mission(variant)
    assert mission.source is not None
    return np.asarray(mission.source.snr_db(positions), float)


def _read_samples(
    paths: Sequence[Path], sensors: Sequence[str], to_local: Any
) -> tuple[np.ndarray, np.ndarray]:
    """(S, 3) positions and (S, N) SNR of recorded flights stacked (one-line errors)."""
    from skymule.io.traces import TraceError, positions_local, read_trace

    positions, snr = [], []
    for path in paths:
        try:
            trace = read_trace(path, sensors=sensors)
        except TraceError as exc:
            raise SkymuleError(str(exc)) from None
        except OSError as exc:
            raise SkymuleError(f"{path}: cannot read the flight ({exc.strerror})") from None
        positions.append(positions_local(trace, to_local))
        snr.append(np.asarray(trace.snr_db, float))
    return np.vstack(positions), np.vstack(snr)


def _references(
    base: Scenario,
    real_trace: Path,
    positions: np.ndarray,
    measured: np.ndarray,
    names: Sequence[str],
    sensor_m: np.ndarray,
    calibration: Sequence[Path],
    twins: Sequence[str],
    frame: Any,
    rate_bps: Any,
    boot: Bootstrap,
) -> tuple[list[Reference], list[str]]:
    """The reference rows and the notes on what they were made from."""
    notes: list[str] = []
    window = f"running median of {NOISE_WINDOW} samples"
    rows = [Reference("noise floor", window, score_predictions(
        _noise_floor(measured), measured, names, rate_bps, boot))]  # fmt: skip
    if not np.isfinite(sensor_m).all():
        notes.append(
            "the scenario gives no tower positions: no free-space or log-distance reference"
        )
        return rows, notes
    rows.append(Reference("free space", "the scenario's link budget", score_predictions(
        _free_space(base, real_trace, positions), measured, names, rate_bps, boot)))  # fmt: skip
    fit_on = list(calibration) or [Path(t) for t in twins if is_trace_file(t)]
    if fit_on:
        fit_positions, fit_snr = _read_samples(fit_on, names, frame.to_local)
        label = ", ".join(p.name for p in fit_on)
        if not calibration:
            notes.append(
                f"log-distance reference fitted on the twins' flights ({label}); give "
                "--calibration with what the twins were calibrated on"
            )
        predicted = _log_distance(fit_positions, fit_snr, sensor_m, positions)
        rows.append(Reference("log-distance", label, score_predictions(
            predicted, measured, names, rate_bps, boot)))  # fmt: skip
    else:
        notes.append(
            "no calibration set: give --calibration (what the twins were calibrated on) for "
            "the log-distance reference"
        )
    oracle = _log_distance(positions, measured, sensor_m, positions)
    rows.append(Reference("oracle log-distance", "the scored samples themselves (a yardstick)",
                          score_predictions(oracle, measured, names, rate_bps, boot)))  # fmt: skip
    return rows, notes


def mean_regret(numbers: Sequence[PolicyNumbers], boot: Bootstrap) -> Estimate:
    """The mean of the policies' regrets, its interval from one joint bootstrap over slots
    (every policy's slots resampled with the same blocks)."""
    if len(numbers) == 1:
        return numbers[0].regret
    series = [s for n in numbers for s in (n.executed_bit, n.best_bit)]
    width = max(s.size for s in series)
    padded = [np.pad(s, (0, width - s.size)) for s in series]

    def mean(*arrays: np.ndarray) -> np.ndarray:
        values = []
        for executed, best in zip(arrays[::2], arrays[1::2], strict=True):
            total = np.sum(best, axis=-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                values.append(np.where(total > 0, (total - np.sum(executed, axis=-1)) / total,
                                       np.nan))  # fmt: skip
        return _nan_mean(np.stack(values), axis=0)

    return block_bootstrap(mean, padded, boot)


def _nan_mean(values: Any, axis: int | None = None) -> Any:
    """The mean of the finite values (NaN where there is none), without a warning."""
    values = np.asarray(values, float)
    finite_ = np.isfinite(values)
    count = finite_.sum(axis=axis)
    total = np.where(finite_, values, 0.0).sum(axis=axis)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def sim2real(
    scenario: str | Scenario,
    real_trace: Path,
    twins: Sequence[str],
    policies: Sequence[str],
    *,
    calibration: Sequence[Path] = (),
    download_log: Path | None = None,
    boot: Bootstrap = DEFAULT_BOOTSTRAP,
) -> Sim2Real:
    """Score every twin against the real flight ``real_trace`` (see the module docstring).

    ``calibration``: the flights the twins were calibrated on (the log-distance reference is
    fitted on them); ``download_log``: the real flight's download log (its serving decisions
    are then the same decisions of the same-decisions error).
    """
    from skymule.geo import sensor_positions_m
    from skymule.io.traces import TraceError, positions_local, read_trace
    from skymule.policies import check_policies
    from skymule.world import build_mission

    if not twins:
        raise SkymuleError("sim2real: give at least one --twin (a map .json, a flight .csv or a "
                           "scenario)")  # fmt: skip
    for path in calibration:
        if not Path(path).is_file():
            raise SkymuleError(f"--calibration {path}: no such file (a recorded flight .csv)")
    names = check_policies(list(policies))
    base = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    label = str(scenario) if not isinstance(scenario, Scenario) else scenario.name
    real = build_mission(real_variant(base, real_trace))
    sensors = base.signal.sensors_from_trace or [s.name for s in base.sensors]
    try:
        recorded = read_trace(real_trace, sensors=sensors)
    except TraceError as exc:
        raise SkymuleError(str(exc)) from None
    real_runs = _runs(real.scenario, names, real)
    real_rates = _track_rates(next(iter(real_runs.values())))
    positions = positions_local(recorded, real.frame.to_local)
    measured = np.asarray(recorded.snr_db, float)
    recorded_same = None
    if download_log is not None:
        recorded_same = _recorded_decisions(download_log, real_trace, real)
    results, frames = [], []
    for twin in twins:
        variant = twin_variant(base, real_trace, twin)
        mission = build_mission(variant)
        assert mission.source is not None
        twin_positions = positions_local(recorded, mission.frame.to_local)
        predicted = np.asarray(mission.source.snr_db(twin_positions), float)
        sigma_of = getattr(mission.source, "sigma_db", None)
        sigma = None if sigma_of is None else np.asarray(sigma_of(twin_positions), float)
        scores = score_predictions(
            predicted, measured, mission.sensor_names, mission.rate_bps, boot, sigma
        )
        twin_runs = _runs(variant, names, mission)
        twin_rates = _track_rates(next(iter(twin_runs.values())))
        numbers = {
            p: policy_numbers(
                real_runs[p],
                twin_runs[p],
                recorded_same or _decisions_of(real_runs[p]),
                real_rates,
                twin_rates,
                boot,
            )
            for p in names
        }
        results.append(TwinResult(twin, scores, numbers))
        frames.append(
            _samples(twin, recorded.time_s, measured, predicted, sigma, mission.sensor_names)
        )
    sensor_m = sensor_positions_m(base.sensors, real.frame) if base.sensors else np.full(
        (len(real.sensor_names), 3), np.nan)  # fmt: skip
    references, notes = _references(
        base, real_trace, positions, measured, real.sensor_names, sensor_m,
        calibration, twins, real.frame, real.rate_bps, boot,
    )  # fmt: skip
    notes += worse_than_references(results, references)
    ranking = rank_twins(results, boot)
    real_mbit = {p: float(r.summary["total_downloaded_mbit"]) for p, r in real_runs.items()}
    return Sim2Real(
        label, str(real_trace), real_mbit, tuple(results), pd.concat(frames),
        tuple(references), tuple(ranking), boot, tuple(notes),
    )  # fmt: skip


BASELINES = ("free space", "log-distance")
"""References a twin should beat: a formula, and a trend fitted on the calibration set."""


def mean_rmse(scores: Scores) -> float:
    """The mean over the towers of the SNR RMSE [dB] (NaN towers left out)."""
    return float(_nan_mean([row["rmse_db"].value for row in scores.towers.values()]))


def worse_than_references(
    results: Sequence[TwinResult], references: Sequence[Reference]
) -> list[str]:
    """One note per twin whose mean SNR RMSE is above a baseline reference's."""
    notes = []
    baselines = [r for r in references if r.reference in BASELINES]
    for result in results:
        own = mean_rmse(result.metrics)
        worse = [(r.reference, mean_rmse(r.scores)) for r in baselines]
        worse = [(name, value) for name, value in worse if own > value]
        if worse:
            than = ", ".join(f"{name} ({value:.1f} dB)" for name, value in worse)
            notes.append(f"{label_of(result.twin)}: mean SNR RMSE {own:.1f} dB, worse than {than}")
    return notes


def rank_twins(results: Sequence[TwinResult], boot: Bootstrap) -> list[Ranked]:
    """Twins in increasing order of mean decision regret (ties: smaller mean |same-decisions
    error|, then smaller mean SNR RMSE)."""
    ranked = [
        Ranked(
            result.twin,
            mean_regret(list(result.numbers.values()), boot),
            float(_nan_mean([abs(n.same_decisions_error.value) for n in result.numbers.values()])),
            mean_rmse(result.metrics),
        )
        for result in results
    ]
    order = rank_by([(r.regret.value, r.same_decisions_error, r.rmse_db) for r in ranked])
    return [ranked[i] for i in order]


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
    atomic.write_text(document, json.dumps(finite(result.to_json()), indent=2) + "\n")
    return [document, samples]


def finite(value: Any) -> Any:
    """``value`` with NaN and infinities as None (strict JSON)."""
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


# --- tables: one format for the terminal and the report, read from the JSON document ------

DB_PLACES, MBPS_PLACES, PERCENT_PLACES, COVERAGE_PLACES = 1, 2, 1, 0
"""Decimals of a column: dB, Mbit/s, a policy-level % and a coverage %."""
SNR_COLUMNS = {
    "rmse_db": ("RMSE [dB]", DB_PLACES, 1.0),
    "bias_db": ("bias [dB]", DB_PLACES, 1.0),
    "mae_db": ("MAE [dB]", DB_PLACES, 1.0),
    "rate_rmse_mbps": ("rate RMSE [Mbit/s]", MBPS_PLACES, 1.0),
    "rate_bias_mbps": ("rate bias [Mbit/s]", MBPS_PLACES, 1.0),
    "coverage_95": ("in 95% interval [%]", COVERAGE_PLACES, 100.0),
}
"""JSON metric -> (column header, decimals, scale)."""
POLICY_COLUMNS = (
    "twin", "policy", "decisions", "same-decisions error [%]", "regret [%]", "own error [%]",
    "hover slots real/twin", "last sample real/twin",
)  # fmt: skip
RANKING_COLUMNS = ("rank", "twin", "regret [%]", "|same-decisions error| [%]", "SNR RMSE [dB]")


def fmt_ci(value: Any, ci: Any, places: int, scale: float = 1.0) -> str:
    """``value [low, high]`` with ``places`` decimals after multiplying by ``scale``;
    ``n/a`` for a missing value, the value alone without an interval."""
    if value is None or not math.isfinite(float(value)):
        return "n/a"
    text = _fixed(float(value) * scale, places)
    if ci and all(c is not None and math.isfinite(float(c)) for c in ci):
        low, high = (float(c) * scale for c in ci)
        text += f" [{_fixed(low, places)}, {_fixed(high, places)}]"
    return text


def _fixed(value: float, places: int) -> str:
    """``value`` with ``places`` decimals, never ``-0.0``."""
    text = f"{value:.{places}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def label_of(name: str) -> str:
    """A twin's short name: a file's name, or the scenario/preset as given."""
    return Path(name).name if ("/" in name or "\\" in name) else name


def _snr_group(name: str, group: dict[str, Any]) -> list[dict[str, str]]:
    rows = []
    ci = group.get("ci", {})
    for sensor in group["rmse_db"]:
        row = {"row": name, "sensor": sensor}
        for metric, (header, places, scale) in SNR_COLUMNS.items():
            value = (group.get(metric) or {}).get(sensor)
            row[header] = fmt_ci(value, ci.get(metric, {}).get(sensor), places, scale)
        rows.append(row)
    best = group.get("best_link") or {}
    row = {"row": name, "sensor": BEST_LINK}
    for metric, (header, places, scale) in SNR_COLUMNS.items():
        row[header] = fmt_ci(best.get(metric), (best.get("ci") or {}).get(metric), places, scale)
    return [*rows, row]


def snr_table(document: dict[str, Any]) -> tuple[list[str], list[dict[str, str]]]:
    """The SNR table of a ``sim2real`` JSON document: twins' rows, then the references'
    (``ref: ...``); every cell ``value [CI]``."""
    rows = []
    for twin in document["twins"]:
        rows += _snr_group(label_of(twin["twin"]), twin)
    for ref in document.get("references", []):
        rows += _snr_group(f"ref: {ref['reference']}", ref)
    return ["row", "sensor", *(h for h, _, _ in SNR_COLUMNS.values())], rows


def _percent(entry: dict[str, Any], key: str) -> str:
    return fmt_ci(entry.get(key), entry.get(f"{key}_ci"), PERCENT_PLACES, 100.0)


def policy_table(document: dict[str, Any]) -> tuple[list[str], list[dict[str, str]]]:
    """The policy-level table: the three numbers [%] with CIs, hover slots, last samples."""
    rows = []
    for twin in document["twins"]:
        for policy, v in twin["policies"].items():
            defined = v.get("own_error") is not None
            samples = f"{v.get('last_sample_real')}/{v.get('last_sample_twin')}"
            cells = [
                label_of(twin["twin"]),
                policy,
                str(v.get("decisions", "")),
                _percent(v, "same_decisions_error"),
                _percent(v, "regret"),
                _percent(v, "own_error") if defined else "undefined: hovers",
                f"{v.get('hover_slots_real')}/{v.get('hover_slots_twin')}",
                f"{samples} of {v.get('n_samples')}",
            ]
            rows.append(dict(zip(POLICY_COLUMNS, cells, strict=True)))
    return list(POLICY_COLUMNS), rows


def ranking_table(document: dict[str, Any]) -> tuple[list[str], list[dict[str, str]]]:
    """Twins by decision regret (mean over the policies), best first."""
    rows = [
        {
            "rank": str(i),
            "twin": label_of(r["twin"]),
            "regret [%]": fmt_ci(r["regret"], r["regret_ci"], PERCENT_PLACES, 100.0),
            "|same-decisions error| [%]": fmt_ci(
                r["same_decisions_error"], None, PERCENT_PLACES, 100.0
            ),
            "SNR RMSE [dB]": fmt_ci(r["rmse_db"], None, DB_PLACES),
        }
        for i, r in enumerate(document.get("ranking", []), start=1)
    ]
    return list(RANKING_COLUMNS), rows


__all__ = [
    "RESULT_JSON",
    "SAMPLES_CSV",
    "PolicyNumbers",
    "Ranked",
    "Reference",
    "Scores",
    "Sim2Real",
    "TwinResult",
    "fmt_ci",
    "policy_table",
    "ranking_table",
    "sim2real",
    "snr_table",
    "write_sim2real",
]
