"""Radio maps fitted to recorded flights: log-distance trend + kriged residual field.

Per sensor i, with d the 3-D UAV-antenna distance [m] and SNR measured at UAV positions x_k:

1. Trend: SNR(d) = A - 10 n log10(d / 1 m), A [dB] and exponent n by ordinary least squares
   on the valid samples (the log-distance model, Rappaport 2nd ed. eq. 4.68, fitted as in
   empirical path-loss studies).
2. Residual r_k = SNR_k - trend(d_k), modelled as a zero-mean Gaussian field with exponential
   covariance sigma^2 exp(-h / L) (Gudmundson 1991) plus a nugget tau^2 (measurement noise,
   fast fading). sigma^2, L, tau^2 are estimated from the empirical semivariogram
   gamma(h) = mean over pairs at lag ~h of (r_j - r_k)^2 / 2 (Matheron; Cressie, *Statistics
   for Spatial Data*, 1993, eq. 2.4.2), fitted to tau^2 + sigma^2 (1 - exp(-h / L)) by
   pair-count-weighted least squares (Cressie 1985) over a grid of L.
3. Prediction at x: trend(d(x)) + k(x)^T (K + tau^2 I)^{-1} r, the simple-kriging / Gaussian-
   process posterior mean (Rasmussen & Williams, *Gaussian Processes for Machine Learning*,
   2006, eq. 2.25), k and K from the exponential covariance. It reproduces the measurements
   where the UAV flew (up to the nugget) and falls back to the fitted trend far from them.
   Bulk queries split the kernel into an exact near part (zero beyond 2 L) and a smooth far
   part splined from a grid (:func:`krige_split`, within 0.01 dB of the dense sum, tested).

Missing samples (NaN; -99 in digital-twin exports) and deep drops (below ``drop_below_db``,
real but unpredictable link losses) are excluded and counted. At most ``MAX_KRIGING_POINTS``
samples per sensor (evenly thinned in time) enter the kriging system. Fit quality: in-sample
RMSE and K-fold cross-validated RMSE with each fold one contiguous segment of every trace
(trend and kriging weights refitted without the held-out segment; variogram parameters kept).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from skymule.errors import ScenarioError, SkymuleError
from skymule.geo import LocalFrame
from skymule.io import atomic
from skymule.radio.kriging import (
    MAX_KRIGING_POINTS,
    Variogram,
    fit_variogram,
    krige,
    kriging_weights,
    thin_indices,
)
from skymule.radio.pathloss import MIN_DISTANCE_M

DEEP_DROP_DB = -40.0
"""SNR samples below this [dB] are deep drops (link losses): excluded from fits and scores."""

MIN_FIT_SAMPLES = 20
"""A sensor needs at least this many valid samples to fit its map."""


CV_FOLDS = 5
"""Cross-validation folds (contiguous segments of each trace)."""


MAP_FORMAT = "skymule-radiomap"
MAP_VERSION = 1


@dataclass(frozen=True, eq=False)
class SensorMap:
    """The fitted map of one sensor (SNR in dB at UAV positions in the map's frame).

    Attributes:
        name: sensor name.
        position_m: (3,) antenna position [m].
        intercept_db: A, the trend's SNR at 1 m [dB].
        exponent: n, the path-loss exponent.
        variogram: residual field parameters.
        train_m: (S, 3) kriging sample positions [m].
        weights: (S,) kriging weights (K + tau^2 I)^{-1} r [dB].
        stats: fit quality and sample counts (see :func:`fit_sensor_map`).
    """

    name: str
    position_m: np.ndarray
    intercept_db: float
    exponent: float
    variogram: Variogram
    train_m: np.ndarray
    weights: np.ndarray
    stats: dict[str, float] = field(default_factory=dict)

    def trend_db(self, positions_m: np.ndarray) -> np.ndarray:
        """(P,) log-distance trend [dB] at positions (P, 3)."""
        return trend_db(positions_m, self.position_m, self.intercept_db, self.exponent)

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray:
        """(P,) predicted SNR [dB] at positions (P, 3): trend + kriged residual."""
        positions = np.atleast_2d(np.asarray(positions_m, float))
        return self.trend_db(positions) + krige(
            positions, self.train_m, self.weights, self.variogram
        )


def distance_m(positions_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
    """(P,) 3-D distances [m], clipped below at MIN_DISTANCE_M."""
    d = np.linalg.norm(np.asarray(positions_m, float) - np.asarray(sensor_m, float), axis=-1)
    return np.maximum(d, MIN_DISTANCE_M)


def trend_db(
    positions_m: np.ndarray, sensor_m: np.ndarray, intercept_db: float, exponent: float
) -> np.ndarray:
    """(P,) SNR trend A - 10 n log10(d) [dB]."""
    return intercept_db - 10.0 * exponent * np.log10(distance_m(positions_m, sensor_m))


def fit_trend(distance: np.ndarray, snr_db: np.ndarray) -> tuple[float, float]:
    """Least-squares (A, n) of SNR = A - 10 n log10(d) (distances [m], SNR [dB], shape (S,))."""
    design = np.column_stack([np.ones_like(distance), -10.0 * np.log10(distance)])
    (intercept, exponent), *_ = np.linalg.lstsq(design, snr_db, rcond=None)
    return float(intercept), float(exponent)


@dataclass(frozen=True)
class SensorSamples:
    """One sensor's measurements gathered from one or more traces.

    positions_m (S, 3), snr_db (S,) with NaN for missing samples, segment (S,) CV fold of each
    sample (contiguous segments of each trace).
    """

    positions_m: np.ndarray
    snr_db: np.ndarray
    segment: np.ndarray


def valid_mask(snr_db: np.ndarray, drop_below_db: float) -> tuple[np.ndarray, int, int]:
    """(usable mask, number missing, number of deep drops) of SNR samples."""
    missing = ~np.isfinite(snr_db)
    deep = ~missing & (snr_db < drop_below_db)
    return ~(missing | deep), int(missing.sum()), int(deep.sum())


def _fit_core(
    positions: np.ndarray, snr: np.ndarray, sensor_m: np.ndarray, variogram: Variogram | None
) -> tuple[float, float, Variogram, np.ndarray, np.ndarray]:
    intercept, exponent = fit_trend(distance_m(positions, sensor_m), snr)
    residual = snr - trend_db(positions, sensor_m, intercept, exponent)
    keep = thin_indices(len(snr), MAX_KRIGING_POINTS)
    if variogram is None:
        variogram = fit_variogram(positions[keep], residual[keep])
    weights = kriging_weights(positions[keep], residual[keep], variogram)
    return intercept, exponent, variogram, positions[keep], weights


def fit_sensor_map(
    name: str,
    sensor_m: np.ndarray,
    samples: SensorSamples,
    *,
    drop_below_db: float = DEEP_DROP_DB,
    baseline_snr_db: np.ndarray | None = None,
    label: str = "traces",
) -> SensorMap:
    """Fit one sensor's map; ``stats`` holds counts, RMSE and cross-validated RMSE [dB].

    ``baseline_snr_db`` (S,) is a reference model's SNR at the samples (e.g. free space); its
    RMSE on the held-out segments is reported as ``cv_rmse_baseline_db``.
    """
    ok, n_missing, n_deep = valid_mask(samples.snr_db, drop_below_db)
    n_used = int(ok.sum())
    if n_used < MIN_FIT_SAMPLES:
        raise SkymuleError(
            f"{label}: sensor {name} has {n_used} valid SNR samples ({n_missing} missing, "
            f"{n_deep} deep drops below {drop_below_db:g} dB); fitting a radio map needs at "
            f"least {MIN_FIT_SAMPLES}"
        )
    positions, snr, segment = samples.positions_m[ok], samples.snr_db[ok], samples.segment[ok]
    sensor = np.asarray(sensor_m, float)
    intercept, exponent, vario, train, weights = _fit_core(positions, snr, sensor, None)
    fitted = SensorMap(name, sensor, intercept, exponent, vario, train, weights)
    errors: dict[str, list[np.ndarray]] = {"map": [], "trend": [], "baseline": []}
    for fold in np.unique(segment):
        test = segment == fold
        if test.all() or (~test).sum() < MIN_FIT_SAMPLES // 2:
            continue
        a, n, _, tr, w = _fit_core(positions[~test], snr[~test], sensor, vario)
        trend = trend_db(positions[test], sensor, a, n)
        errors["trend"].append(trend - snr[test])
        errors["map"].append(trend + krige(positions[test], tr, w, vario) - snr[test])
        if baseline_snr_db is not None:
            errors["baseline"].append(baseline_snr_db[ok][test] - snr[test])
    stats = {
        "n_used": float(n_used),
        "n_missing": float(n_missing),
        "n_deep_drops": float(n_deep),
        "rmse_db": _rmse(fitted.snr_db(positions) - snr),
        "rmse_trend_db": _rmse(fitted.trend_db(positions) - snr),
    }
    for key, values in errors.items():
        if values:
            stats[f"cv_rmse_{key}_db"] = _rmse(np.concatenate(values))
    return SensorMap(name, sensor, intercept, exponent, vario, train, weights, stats)


def _rmse(error: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(error)))) if error.size else float("nan")


@dataclass(frozen=True, eq=False)
class RadioMap:
    """Fitted maps of several sensors, in the local frame centred on ``origin`` (lat, lon)."""

    origin: tuple[float, float]
    sensors: tuple[SensorMap, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.sensors)

    def sensor(self, name: str, label: str = "radio map") -> SensorMap:
        for sensor_map in self.sensors:
            if sensor_map.name.upper() == name.upper():
                return sensor_map
        raise ScenarioError(
            f"{label}: no map for sensor {name!r}; the map has {', '.join(self.names)}"
        )

    def source(self, names: Sequence[str], offset_m: np.ndarray | None = None) -> RadioMapSource:
        """A signal source for the named sensors, in that order."""
        offset = np.zeros(3) if offset_m is None else np.asarray(offset_m, float)
        return RadioMapSource(tuple(self.sensor(n) for n in names), offset)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": MAP_FORMAT,
            "version": MAP_VERSION,
            "origin": {"lat": self.origin[0], "lon": self.origin[1]},
            "sensors": [
                {
                    "name": s.name,
                    "position_m": s.position_m.tolist(),
                    "intercept_db": s.intercept_db,
                    "exponent": s.exponent,
                    "sill_db2": s.variogram.sill_db2,
                    "range_m": s.variogram.range_m,
                    "nugget_db2": s.variogram.nugget_db2,
                    "stats": s.stats,
                    "train_m": np.round(s.train_m, 3).tolist(),
                    "weights": s.weights.tolist(),
                }
                for s in self.sensors
            ],
        }

    def write(self, path: Path) -> None:
        atomic.write_text(path, json.dumps(self.to_dict()))


def read_radiomap(path: Path) -> RadioMap:
    """Read a map written by :meth:`RadioMap.write` (one-line SkymuleError if it is not one)."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise SkymuleError(f"{path}: radio map file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SkymuleError(f"{path}: not a radio map JSON file ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != MAP_FORMAT:
        raise SkymuleError(
            f'{path}: not a skymule radio map (expected "format": "{MAP_FORMAT}"; '
            "make one with 'skymule fit-radiomap TRACE... --out map.json')"
        )
    try:
        sensors = tuple(
            SensorMap(
                name=s["name"],
                position_m=np.asarray(s["position_m"], float),
                intercept_db=float(s["intercept_db"]),
                exponent=float(s["exponent"]),
                variogram=Variogram(
                    float(s["sill_db2"]), float(s["range_m"]), float(s["nugget_db2"])
                ),
                train_m=np.asarray(s["train_m"], float).reshape(-1, 3),
                weights=np.asarray(s["weights"], float),
                stats={k: float(v) for k, v in s.get("stats", {}).items()},
            )
            for s in data["sensors"]
        )
        origin = (float(data["origin"]["lat"]), float(data["origin"]["lon"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise SkymuleError(f"{path}: radio map is incomplete or malformed ({exc!r})") from None
    return RadioMap(origin, sensors)


@dataclass(frozen=True, eq=False)
class RadioMapSource:
    """Signal source from a fitted map: positions (P, 3) -> SNR (P, N) [dB].

    ``offset_m`` (3,) is added to query positions to move them into the map's frame.
    """

    maps: tuple[SensorMap, ...]
    offset_m: np.ndarray

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray:
        positions = np.atleast_2d(np.asarray(positions_m, float)) + self.offset_m
        return np.column_stack([m.snr_db(positions) for m in self.maps])


# ---------------------------------------------------------------------------
# From trace files
# ---------------------------------------------------------------------------


def load_samples(
    paths: Sequence[Path], names: Sequence[str], frame: LocalFrame, folds: int = CV_FOLDS
) -> list[SensorSamples]:
    """Per sensor (in ``names`` order), the samples of all traces (positions in ``frame``)."""
    from skymule.io.traces import positions_local, read_trace

    positions, snr, segment = [], [], []
    for path in paths:
        trace = read_trace(path, sensors=list(names))  # names a missing column in one line
        positions.append(positions_local(trace, frame.to_local))
        snr.append(trace.snr_db)
        segment.append(np.minimum(np.arange(trace.n_samples) * folds // trace.n_samples, folds - 1))
    all_pos, all_snr, all_seg = np.vstack(positions), np.vstack(snr), np.concatenate(segment)
    return [SensorSamples(all_pos, all_snr[:, j], all_seg) for j in range(len(names))]


def fit_radiomap(
    paths: Sequence[Path],
    names: Sequence[str],
    sensor_m: np.ndarray,
    frame: LocalFrame,
    *,
    drop_below_db: float = DEEP_DROP_DB,
    baseline: Any = None,
) -> RadioMap:
    """Fit a map for each named sensor (antennas at ``sensor_m`` (N, 3)) to the traces.

    ``baseline`` is an optional signal source (e.g. free space) scored on the same
    cross-validation segments for comparison.
    """
    label = ", ".join(str(p) for p in paths)
    samples = load_samples(paths, names, frame)
    base = None if baseline is None else baseline.snr_db(samples[0].positions_m)
    maps = tuple(
        fit_sensor_map(
            name,
            sensor_m[j],
            samples[j],
            drop_below_db=drop_below_db,
            baseline_snr_db=None if base is None else base[:, j],
            label=label,
        )
        for j, name in enumerate(names)
    )
    return RadioMap((frame.origin_lat_deg, frame.origin_lon_deg), maps)


def frame_offset_m(map_origin: tuple[float, float], frame: LocalFrame) -> np.ndarray:
    """(3,) shift from ``frame`` coordinates to a map's frame (small-site translation)."""
    x_m, y_m = frame.to_local(map_origin[0], map_origin[1])
    return -np.array([float(x_m), float(y_m), 0.0])


def scenario_radiomap_source(
    scenario: Any, frame: LocalFrame, sensor_m: np.ndarray
) -> RadioMapSource:
    """The radio-map source of a scenario's ``[signal]`` section (fit traces or read a map)."""
    signal = scenario.signal
    names = signal.sensors_from_trace or [s.name for s in scenario.sensors]
    if len(names) != len(scenario.sensors):
        raise ScenarioError(
            f"signal.sensors_from_trace has {len(names)} names for {len(scenario.sensors)} "
            "sensors; give one trace column per sensor"
        )
    if signal.map:
        path = scenario.resolve_path(signal.map)
        fitted = read_radiomap(path)
        for name in names:
            fitted.sensor(name, label=f"signal.map = {str(path)!r}")
        return fitted.source(names, frame_offset_m(fitted.origin, frame))
    missing = [s.name for s in scenario.sensors if not s.has_position]
    if missing:
        raise ScenarioError(
            f"sensors {', '.join(missing)}: fitting a radio map needs each sensor's position"
        )
    paths = [scenario.resolve_path(p) for p in signal.traces]
    return fit_radiomap(paths, names, sensor_m, frame).source(names)


# ---------------------------------------------------------------------------
# Scoring a source against a recorded flight
# ---------------------------------------------------------------------------


def score_source(
    predicted_db: np.ndarray,
    measured_db: np.ndarray,
    names: Sequence[str],
    rate_bps: Any,
    drop_below_db: float = DEEP_DROP_DB,
) -> dict[str, dict[str, float]]:
    """Per-sensor RMSE and bias (predicted - measured) of SNR [dB] and rate [Mbit/s].

    Missing samples and deep drops of the measurement are left out and counted.
    """
    out: dict[str, dict[str, float]] = {
        k: {}
        for k in (
            "rmse_db",
            "bias_db",
            "rate_rmse_mbps",
            "rate_bias_mbps",
            "n_scored",
            "n_missing",
            "n_deep_drops",
        )
    }
    for j, name in enumerate(names):
        ok, n_missing, n_deep = valid_mask(measured_db[:, j], drop_below_db)
        error = predicted_db[ok, j] - measured_db[ok, j]
        rate_error = (rate_bps(predicted_db[ok, j]) - rate_bps(measured_db[ok, j])) / 1e6
        out["rmse_db"][name] = _rmse(error)
        out["bias_db"][name] = float(error.mean()) if error.size else float("nan")
        out["rate_rmse_mbps"][name] = _rmse(rate_error)
        out["rate_bias_mbps"][name] = float(rate_error.mean()) if error.size else float("nan")
        out["n_scored"][name] = int(ok.sum())
        out["n_missing"][name] = n_missing
        out["n_deep_drops"][name] = n_deep
    return out


def site_tower_positions_m(
    names: Sequence[str], frame: LocalFrame, site: str = "lake-wheeler"
) -> np.ndarray:
    """(N, 3) positions [m] of a built-in site's towers by name (one-line error if unknown)."""
    from skymule.geo import load_site

    towers = {p.name.upper(): p for p in load_site(site).towers}
    out = np.zeros((len(names), 3))
    for j, name in enumerate(names):
        tower = towers.get(name.upper())
        if tower is None:
            raise SkymuleError(
                f"sensor {name!r}: not a built-in {site} tower ({', '.join(sorted(towers))}); "
                "pass --scenario with the sensors' positions"
            )
        x_m, y_m = frame.to_local(tower.lat_deg, tower.lon_deg)
        out[j] = [float(x_m), float(y_m), float(tower.antenna_height_m or 0.0)]
    return out
