"""Fit a radio map to recorded flights, and score a map (or a scenario's model) against one.

The API behind ``skymule fit-radiomap`` and ``skymule score-radiomap``::

    from skymule.tasks.radiomaps import fit_radiomap_files, score_against_trace

    fit = fit_radiomap_files([Path("dt_flight.csv")])         # sensors from the trace header
    fit.fitted.write(Path("map.json")); fit.rows              # one dict per sensor
    scores = score_against_trace("map.json", Path("real_flight.csv"))

Positions are in the local frame of the scenario's origin (or ``origin``, lat/lon degrees);
the cross-validation baseline is free space with the scenario's link budget.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from skymule.errors import SkymuleError

if TYPE_CHECKING:
    from skymule.geo import LocalFrame
    from skymule.radio.radiomap import Prior, RadioMap
    from skymule.radio.sources import SignalSource

LatLonDeg = tuple[float, float]


def parse_origin(text: str) -> LatLonDeg:
    """``"LAT,LON"`` in degrees -> (lat, lon), with a one-line error naming ``--origin``."""
    try:
        lat, lon = (float(v) for v in text.split(","))
    except ValueError:
        raise SkymuleError(
            f"--origin {text!r}: expected LAT,LON in degrees, e.g. 35.7274824,-78.6962749"
        ) from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise SkymuleError(f"--origin {text!r}: latitude must be -90..90, longitude -180..180")
    return lat, lon


def _frame(origin: LatLonDeg | None, default: LatLonDeg) -> LocalFrame:
    from skymule.geo import LocalFrame

    return LocalFrame(*(origin if origin is not None else default))


@dataclass(frozen=True)
class RadioMapFit:
    """A fitted map and its per-sensor table (fit parameters and cross-validated RMSEs)."""

    fitted: RadioMap
    rows: list[dict[str, Any]]
    warnings: tuple[str, ...] = ()
    """One line per sensor whose fit is degenerate, and one if no map beats the baseline on
    held-out blocks (:func:`fit_warnings`)."""
    note: str | None = None
    """``neural``: one line saying which sensors fell back to a simpler model, and why."""

    COLUMNS = (
        "sensor", "model", "exponent", "intercept_db", "sigma_db", "range_m", "nugget_db",
        "n_used", "n_missing", "n_deep_drops", "rmse_db", "cv_rmse_map_db", "cv_rmse_trend_db",
        "cv_rmse_baseline_db", "cv_coverage_95",
    )  # fmt: skip
    LEARNED_COLUMNS = ("cv_rmse_prior_db", "cv_rmse_network_db")
    """Columns of ``neural`` fits (with a prior: its raw RMSE), printed after ``COLUMNS``."""

    def columns(self) -> tuple[str, ...]:
        """The table's columns: ``COLUMNS``, then the ``LEARNED_COLUMNS`` the rows have."""
        extra = [c for c in self.LEARNED_COLUMNS if any(c in row for row in self.rows)]
        return (*self.COLUMNS, *extra)


def is_map_file(spec: str) -> bool:
    """True for a radio-map JSON path (``*.json``)."""
    return spec.lower().endswith(".json")


def is_trace_file(spec: str) -> bool:
    """True for a recorded flight (``*.csv``: an AADM merged log or a digital-twin export)."""
    return spec.lower().endswith(".csv")


def resolve_prior(
    spec: str, names: Sequence[str], sensor_m: np.ndarray, frame: LocalFrame
) -> Prior:
    """The prior (a twin) a learned map calibrates, from ``--prior``.

    A radio-map JSON is held as it is; a recorded flight (a DT export or merged log) is
    fitted to a kriging map first; a scenario or preset gives its path-loss model and link
    budget (its sensors' positions where it has them, else ``sensor_m``), without shadowing.
    """
    from skymule.geo import sensor_positions_m
    from skymule.radio.radiomap import (
        MapPrior,
        ModelPrior,
        fit_radiomap,
        frame_offset_m,
        read_radiomap,
    )
    from skymule.scenario import load_scenario

    if is_map_file(spec):
        fitted = read_radiomap(Path(spec))
        for name in names:
            fitted.sensor(name, label=f"--prior {spec}")
        return MapPrior(fitted, frame_offset_m(fitted.origin, frame), spec)
    if is_trace_file(spec):
        fitted = fit_radiomap([Path(spec)], names, sensor_m, frame)
        return MapPrior(fitted, np.zeros(3), spec)
    scenario = load_scenario(spec)
    if scenario.signal.source != "model":
        raise SkymuleError(
            f"--prior {spec}: signal.source = {scenario.signal.source!r}; a scenario prior gives "
            "its path-loss model (source = 'model'); pass a map (.json) or a flight (.csv) "
            "instead"
        )
    own = {s.name.upper(): s for s in scenario.sensors if s.has_position}
    own_m = sensor_positions_m(scenario.sensors, frame) if own else np.zeros((0, 3))
    index = {s.name.upper(): i for i, s in enumerate(scenario.sensors)}
    positions: dict[str, tuple[float, float, float]] = {}
    for j, name in enumerate(names):
        xyz = own_m[index[name.upper()]] if name.upper() in own else sensor_m[j]
        positions[name.upper()] = (float(xyz[0]), float(xyz[1]), float(xyz[2]))
    return ModelPrior(scenario.radio.model_dump(mode="json"), positions, spec)


def fit_radiomap_files(
    traces: Sequence[Path],
    *,
    scenario: str | None = None,
    origin: LatLonDeg | None = None,
    drop_below_db: float = -40.0,
    method: str = "kriging",
    prior: str | None = None,
    seed: int = 0,
) -> RadioMapFit:
    """Fit a radio map per sensor to recorded flights, by ``method`` (``METHODS``).

    Sensors, positions, origin and link budget come from ``scenario`` (a path or preset) when
    given; otherwise the sensors are the first trace's SNR columns at the Lake Wheeler towers.
    ``prior`` (``neural`` only): a map, flight or scenario whose prediction the map learns
    to correct (:func:`resolve_prior`); ``seed`` seeds the networks.
    """
    from skymule.geo import sensor_positions_m
    from skymule.io.traces import read_trace
    from skymule.radio.radiomap import METHODS, FitOptions, fit_radiomap, site_tower_positions_m
    from skymule.radio.sources import model_source
    from skymule.registry import did_you_mean
    from skymule.scenario import RadioSpec, SiteSpec, load_scenario

    if not traces:
        raise SkymuleError("fit-radiomap: give at least one recorded flight")
    if method not in METHODS:
        raise SkymuleError(
            f"--method {method!r}: allowed: {', '.join(METHODS)}{did_you_mean(method, METHODS)}"
        )
    if prior is not None and method != "neural":
        raise SkymuleError(
            f"--prior calibrates a learned map: it needs --method neural, not {method!r}"
        )
    traces, prior_as_data = _without_the_prior(traces, prior)
    spec = load_scenario(scenario) if scenario else None
    site = spec.site.origin if spec else SiteSpec().origin
    frame = _frame(origin, (site.lat, site.lon))
    if spec is not None:
        names = spec.signal.sensors_from_trace or [s.name for s in spec.sensors]
        sensor_m = sensor_positions_m(spec.sensors, frame)
        radio = spec.radio
    else:
        names = list(read_trace(traces[0]).columns)
        sensor_m = site_tower_positions_m(names, frame)
        radio = RadioSpec()
    baseline = model_source(radio.model_copy(update={"model": "fspl"}), sensor_m)
    fitted = fit_radiomap(
        list(traces),
        names,
        sensor_m,
        frame,
        drop_below_db=drop_below_db,
        baseline=baseline,
        options=FitOptions(method, seed),
        prior=None if prior is None else resolve_prior(prior, names, sensor_m, frame),
    )
    rows = [
        {
            "sensor": m.name,
            "model": method if m.ensemble is None else m.ensemble.choice,
            "exponent": m.exponent,
            "intercept_db": m.intercept_db,
            "sigma_db": m.variogram.sill_db2**0.5,
            "range_m": m.variogram.range_m,
            "nugget_db": m.variogram.nugget_db2**0.5,
            **m.stats,
        }
        for m in fitted.sensors
    ]
    warnings = (*prior_as_data, *fit_warnings(rows, method))
    return RadioMapFit(fitted, rows, warnings, fallback_note(rows, method))


def _without_the_prior(
    traces: Sequence[Path], prior: str | None
) -> tuple[list[Path], tuple[str, ...]]:
    """The flights to learn from: a flight that is also ``--prior`` is the prior only. As data
    it would teach the map the twin's own errors (its networks then win the cross-validation
    on the twin's samples and lose on a real flight), and the prior already carries what it
    says. Returns the flights kept and a line saying what was left out."""
    if prior is None or not Path(prior).is_file():
        return list(traces), ()
    same = Path(prior).resolve()
    kept = [t for t in traces if Path(t).resolve() != same]
    if not kept:
        raise SkymuleError(
            f"fit-radiomap: {prior} is the --prior and the only flight; give the real flight(s)"
            " to learn the correction from"
        )
    if len(kept) == len(traces):
        return kept, ()
    return kept, (f"{prior} is the --prior: used as the prior only, not as data",)


def fallback_note(rows: Sequence[dict[str, Any]], method: str) -> str | None:
    """``neural``: one line naming the sensors whose map is a simpler model than the networks
    (blocked cross-validation found the networks no better), with both RMSEs; None if every
    sensor kept its networks (or for other methods)."""
    if method != "neural":
        return None
    fell = [r for r in rows if r["model"] != "network"]
    if not fell:
        return None
    parts = [
        f"{r['sensor']} is {r['model']} ({r['cv_rmse_map_db']:.2f} dB vs the networks' "
        f"{r['cv_rmse_network_db']:.2f} dB)"
        for r in fell
        if "cv_rmse_network_db" in r and "cv_rmse_map_db" in r
    ]
    return (
        "fallback: the networks did not beat a simpler model on held-out blocks (blocked "
        "cross-validation RMSE), so " + "; ".join(parts or [r["sensor"] for r in fell])
    )


NOT_WORSE_DB = 0.1
"""A map within this of the baseline's cross-validated RMSE [dB] is not reported as worse."""

KRIGED_OVER = {"kriging": "log-distance trend", "neural": "learned model"}
"""Methods that krige a residual, and what the map is where there is nothing to krige."""


def fit_warnings(rows: Sequence[dict[str, Any]], method: str = "kriging") -> tuple[str, ...]:
    """A line for each sensor whose kriged residual is degenerate: no spatial structure (the
    variogram fit ends at its shortest range or without a sill), so the map there is the
    method's trend alone, whatever its kriging parameters read. Methods that krige nothing
    (``log-distance``; ``gp`` fits its own kernel) get none. First, one line if the map's
    blocked cross-validated RMSE is worse than the baseline's (free space) for any sensor."""
    from skymule.radio.kriging import NO_SILL_DB2, SHORTEST_RANGE_M

    found = []
    worse = [
        r for r in rows
        if r.get("cv_rmse_map_db", np.nan) > r.get("cv_rmse_baseline_db", np.inf) + NOT_WORSE_DB
    ]  # fmt: skip
    if worse:
        found.append(
            "on held-out blocks the map is worse than free space for "
            + ", ".join(
                f"{r['sensor']} ({r['cv_rmse_map_db']:.2f} vs {r['cv_rmse_baseline_db']:.2f} dB)"
                for r in worse
            )
            + "; free space (a scenario with [radio] model = 'fspl') may be the better twin there"
        )
    trend = KRIGED_OVER.get(method)
    if trend is None:
        return tuple(found)
    for row in rows:
        name, sigma, range_m = row["sensor"], row["sigma_db"], row["range_m"]
        if sigma**2 <= NO_SILL_DB2 or range_m <= SHORTEST_RANGE_M:
            found.append(
                f"{name}: degenerate fit (sigma {sigma:.3f} dB, range {range_m:.1f} m): the "
                f"residual shows no spatial correlation, so the map is the {trend} alone "
                f"there; more samples near {name} may help"
            )
    return tuple(found)


def score_against_trace(
    source: str, trace: Path, *, origin: LatLonDeg | None = None
) -> dict[str, dict[str, float]]:
    """How well a fitted map (``*.json``) or a scenario's model predicts a recorded flight.

    Returns score name -> sensor -> value (SNR and rate RMSE and bias, predicted - measured).
    """
    from skymule.geo import sensor_positions_m
    from skymule.io.traces import positions_local, read_trace
    from skymule.radio.channel import signal_source
    from skymule.radio.radiomap import frame_offset_m, read_radiomap, score_source
    from skymule.radio.rates import rate_bps, resolve_rate_table
    from skymule.scenario import RadioSpec, load_scenario

    model: SignalSource
    if source.lower().endswith(".json"):
        fitted = read_radiomap(Path(source))
        frame = _frame(origin, fitted.origin)
        names = list(fitted.names)
        model = fitted.source(names, frame_offset_m(fitted.origin, frame))
        radio = RadioSpec()
        table = resolve_rate_table(radio.rate_table)
    else:
        spec = load_scenario(source)
        if spec.signal.source == "trace":
            raise SkymuleError(
                f"{source}: signal.source = 'trace' replays a flight and predicts nothing; "
                "score a scenario with a model or radiomap source"
            )
        frame = _frame(origin, (spec.site.origin.lat, spec.site.origin.lon))
        names = spec.signal.sensors_from_trace or [s.name for s in spec.sensors]
        model = signal_source(spec, frame, sensor_positions_m(spec.sensors, frame))
        radio = spec.radio
        table = resolve_rate_table(radio.rate_table, Path(spec.base_dir))
    recorded = read_trace(trace, sensors=names)
    predicted = np.asarray(model.snr_db(positions_local(recorded, frame.to_local)))
    scores: dict[str, dict[str, float]] = score_source(
        predicted, recorded.snr_db, names, lambda snr: rate_bps(table, snr, radio.bandwidth_hz)
    )
    return scores
