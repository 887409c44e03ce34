"""Sim-to-real, measured: twins and learned twins against a "real" flight, split by region.

Synthetic worlds (default): the "truth" is free space at the Lake Wheeler towers (the
paper-sim-fixed link budget) minus an excess loss growing with distance, a sector antenna
pattern per tower (3GPP TR 36.814 element pattern: 12 (angle / 3-dB width)^2 dB, capped),
blockage behind obstacles (tree stands: a loss where the tower-UAV ray passes below the
canopy, soft at the edge), and terrain-like spatially correlated shadowing (Gudmundson, 4 dB,
80 m), plus i.i.d. measurement noise of ``NOISE_DB``: the noise floor no map can beat. The
"twin" (the DT) is that mean smoothed in space (a Gaussian kernel of ``TWIN_SMOOTHING_M``,
and the blockage halved) and optimistic by ``TWIN_BIAS_DB`` (drawn per tower).

Flights: the DT flight flies the paper-sim-fixed lawnmower path at 10 m/s; two "real"
flights fly the same route on other days (other speeds, a few metres off, new noise). Splits,
never random samples: every map sees the DT flight and the seen part of real flight B and is
scored on the rest. **region**: the seen part is its west ``SEEN`` (by x), the held-out part
the east, a region the seen part never flew over (SNR columns only: the held-out part is not
one stretch of flight); **time**: the first ``SEEN`` (policies start the held-out part with
full buffers); **flight**: flight A seen whole, flight B held out.

Reference rows (``ref:``): free space (nothing fitted) and log-distance refitted on the
held-out part itself (an oracle, a yardstick); the noise floor is the "- floor" column, and
synthetic worlds add ``oracle: twin - bias``. After the table, one line per split: the
learned twin (neural + DT prior) against the best baseline row (twin, log-distance fitted on
the seen part, free space; target: at most 0.3 dB worse), against the oracle refit (target:
within 1.5 dB) and its 95% coverage (target 85-99%), each "met" or "MISSED".

Each map is fitted with ``skymule.tasks.radiomaps.fit_radiomap_files`` and scored at the
held-out samples (policies: ``skymule.tasks.sim2real.sim2real``), so what is measured is
what the commands do.

    python benchmarks/bench_sim2real.py                    # 3 worlds
    python benchmarks/bench_sim2real.py --worlds 5 --json benchmarks/results/sim2real.json
    python benchmarks/bench_sim2real.py --dt DT.csv --real REAL.csv [--scenario S]
    python benchmarks/bench_sim2real.py --libraries        # kriging vs scikit-learn's GP

``--dt/--real``: the region and time splits on your own pair of flights (a DT export or
merged log of the digital twin, and a real flight's merged log); sensors and positions from
``--scenario`` (default: the trace columns at the Lake Wheeler towers via paper-sim-fixed);
the noise floor is estimated as SNR minus its 5-sample running median. ``--json PATH``
writes ``{"tables": {"sim2real": {"columns", "rows", "note"}}}`` (the README's table).
SKYMULE_BENCH_TINY=1: one small world (not a measurement).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.ndimage
from threadpoolctl import threadpool_limits

from _sizes import size, tiny
from skymule.flight.paths import sample_path
from skymule.geo import LocalFrame, sensor_positions_m
from skymule.io.traces import (
    Trace,
    positions_local,
    read_trace,
    write_aadm_log,
    write_dt_export,
)
from skymule.metrics.sim2real import running_median
from skymule.radio.shadowing import ShadowingField, shadowing_field
from skymule.radio.sources import model_source
from skymule.scenario import Scenario, load_scenario
from skymule.tasks.radiomaps import fit_radiomap_files
from skymule.tasks.sim2real import sim2real

BASE = "paper-sim-fixed"
NOISE_DB = 2.0
SHADOWING_DB, SHADOWING_M = 4.0, 80.0
TWIN_SMOOTHING_M = 60.0
TWIN_BIAS_DB = (6.0, 14.0)
EXCESS_DB_PER_DECADE = 8.0
BEAMWIDTH_DEG, BACK_LOSS_DB = 70.0, 20.0
OBSTACLES, OBSTACLE_RADIUS_M, OBSTACLE_HEIGHT_M, BLOCKAGE_DB = 6, (30.0, 70.0), 22.0, 12.0
SEEN = 0.4
SECONDS = size(500, 160)
BUFFERS_MBIT = (250.0, 400.0, 350.0, 500.0)
POLICIES = ("greedy", "hgad")
METHODS = (
    ("twin (DT map)", "dt", None),
    ("log-distance", "log-distance", None),
    ("kriging", "kriging", None),
    ("gp", "gp", None),
    ("kriging, DT + seen", "kriging+dt", None),
    ("neural", "neural", None),
    ("neural + DT prior", "neural", "dt"),
)
"""(label, method, prior): the maps compared; every one sees the seen part of the real flight
(the twin alone sees only the DT flight)."""


@dataclass(frozen=True)
class World:
    """A synthetic site: the truth's mean SNR and the twin's, at any positions (P, 3)."""

    sensor_m: np.ndarray
    base: object  # free-space model source
    boresight_rad: np.ndarray
    obstacles: np.ndarray  # (K, 3): x, y, radius [m]
    field: ShadowingField
    smooth_field: ShadowingField
    bias_db: np.ndarray

    def _pattern_db(self, positions: np.ndarray) -> np.ndarray:
        delta = positions[:, None, :2] - self.sensor_m[None, :, :2]
        off = np.angle(np.exp(1j * (np.arctan2(delta[..., 1], delta[..., 0]) - self.boresight_rad)))
        return -np.minimum(12.0 * (np.degrees(off) / BEAMWIDTH_DEG) ** 2, BACK_LOSS_DB)

    def _blockage_db(self, positions: np.ndarray, edge_m: float) -> np.ndarray:
        """Loss where the tower-UAV ray passes below an obstacle's canopy (soft edge)."""
        out = np.zeros((len(positions), len(self.sensor_m)))
        for j, tower in enumerate(self.sensor_m):
            ray = positions - tower
            for x, y, radius in self.obstacles:
                to_centre = np.array([x, y]) - tower[:2]
                length2 = np.maximum((ray[:, :2] ** 2).sum(1), 1e-9)
                t = np.clip((ray[:, :2] @ to_centre) / length2, 0.0, 1.0)
                closest = tower[:2] + t[:, None] * ray[:, :2]
                depth = radius - np.hypot(closest[:, 0] - x, closest[:, 1] - y)
                height = tower[2] + t * ray[:, 2]
                below = 1.0 / (1.0 + np.exp(-(OBSTACLE_HEIGHT_M - height) / 2.0))
                inside = 1.0 / (1.0 + np.exp(-depth / edge_m))
                out[:, j] = np.maximum(out[:, j], BLOCKAGE_DB * inside * below * (t < 0.98))
        return out

    def _common(self, positions: np.ndarray) -> np.ndarray:
        distance = np.linalg.norm(positions[:, None, :] - self.sensor_m[None], axis=-1)
        excess = EXCESS_DB_PER_DECADE * np.log10(np.maximum(distance, 10.0) / 10.0)
        return np.asarray(self.base.snr_db(positions)) - excess  # type: ignore[attr-defined]

    def truth_db(self, positions: np.ndarray) -> np.ndarray:
        """(P, N) the real world's mean SNR [dB] (the noise is added per flight)."""
        return (
            self._common(positions)
            + self._pattern_db(positions)
            - self._blockage_db(positions, edge_m=3.0)
            - self.field.at(positions[:, :2])
        )

    def twin_db(self, positions: np.ndarray) -> np.ndarray:
        """(P, N) the digital twin's SNR [dB]: smoother, optimistic."""
        smooth_pattern = _smoothed_along(self._pattern_db, positions)
        return (
            self._common(positions)
            + smooth_pattern
            - 0.5 * self._blockage_db(positions, edge_m=TWIN_SMOOTHING_M / 2)
            - self.smooth_field.at(positions[:, :2])
            + self.bias_db
        )


def _smoothed_along(fn, positions: np.ndarray) -> np.ndarray:
    """``fn`` averaged over a disc of TWIN_SMOOTHING_M around each position (7 points)."""
    offsets = TWIN_SMOOTHING_M * np.array(
        [[0, 0]] + [[np.cos(a), np.sin(a)] for a in np.linspace(0, 2 * np.pi, 6, endpoint=False)]
    )
    total = 0.0
    for dx, dy in offsets:
        total = total + fn(positions + np.array([dx, dy, 0.0]))
    return total / len(offsets)


def draw_world(seed: int, scenario: Scenario) -> World:
    rng = np.random.default_rng([seed, 2026])
    frame = LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon)
    sensor_m = sensor_positions_m(scenario.sensors, frame)
    region = np.array([[-1200.0, -1200.0], [1200.0, 1200.0]])
    field = shadowing_field(rng, len(sensor_m), SHADOWING_DB, SHADOWING_M, region)
    sigma_nodes = TWIN_SMOOTHING_M / field.spacing_m
    smooth = scipy.ndimage.gaussian_filter(field.values_db, sigma=(0, sigma_nodes, sigma_nodes))
    obstacles = np.column_stack(
        [rng.uniform(-450, 450, OBSTACLES), rng.uniform(-550, 350, OBSTACLES),
         rng.uniform(*OBSTACLE_RADIUS_M, OBSTACLES)]
    )  # fmt: skip
    return World(
        sensor_m=sensor_m,
        base=model_source(scenario.radio, sensor_m),
        boresight_rad=rng.uniform(-np.pi, np.pi, len(sensor_m)),
        obstacles=obstacles,
        field=field,
        smooth_field=ShadowingField(field.origin_m, field.spacing_m, smooth),
        bias_db=rng.uniform(*TWIN_BIAS_DB, len(sensor_m)),
    )


def fly(scenario: Scenario, speed_mps: float, offset_m: tuple[float, float]) -> np.ndarray:
    """(SECONDS, 3) the scenario's path at ``speed_mps``, shifted, one sample a second."""
    waypoints = np.asarray(scenario.trajectory.waypoints, float)
    positions = sample_path(waypoints, speed_mps, 1.0)[:SECONDS]
    return positions + np.array([*offset_m, 0.0])


def write_flights(world: World, scenario: Scenario, folder: Path, seed: int) -> dict[str, Path]:
    """dt.csv (the twin along the path), real_a.csv and real_b.csv (truth + noise)."""
    rng = np.random.default_rng([seed, 7])
    names = [s.name for s in scenario.sensors]
    frame = LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon)
    paths = {}
    dt = fly(scenario, 10.0, (0.0, 0.0))
    time_s = np.arange(len(dt), dtype=float)
    paths["dt"] = write_dt_export(
        folder / "dt.csv", time_s, world.twin_db(dt).round(2), names, dt[:, 0], dt[:, 1], dt[:, 2]
    )
    for key, speed, offset in (("real_a", 11.0, (-5.0, 4.0)), ("real_b", 9.0, (6.0, -3.0))):
        xyz = fly(scenario, speed, offset)
        snr = world.truth_db(xyz) + NOISE_DB * rng.standard_normal((len(xyz), len(names)))
        lat, lon = frame.to_latlon(xyz[:, 0], xyz[:, 1])
        t = np.arange(len(xyz), dtype=float)
        paths[key] = write_aadm_log(
            folder / f"{key}.csv", t, snr.round(2), names, lat.round(8), lon.round(8), xyz[:, 2]
        )
    return paths


def write_part(trace: Trace, keep: np.ndarray, path: Path) -> Path:
    """The samples of ``trace`` where ``keep`` (a mask), time rebased to 0, in its own format."""
    t = trace.time_s[keep] - trace.time_s[keep][0]
    snr = trace.snr_db[keep]
    if trace.format == "dt":
        assert trace.x_m is not None and trace.y_m is not None
        return write_dt_export(
            path, t, snr, trace.columns, trace.x_m[keep], trace.y_m[keep], trace.z_m[keep]
        )
    assert trace.lat_deg is not None and trace.lon_deg is not None
    return write_aadm_log(
        path, t, snr, trace.columns, trace.lat_deg[keep], trace.lon_deg[keep], trace.z_m[keep]
    )


def split_time(trace: Trace) -> np.ndarray:
    """Seen mask of the time split: the first ``SEEN`` of the flight."""
    return np.asarray(trace.time_s < trace.time_s[0] + SEEN * (trace.time_s[-1] - trace.time_s[0]))


def split_region(trace: Trace, frame: LocalFrame) -> np.ndarray:
    """Seen mask of the region split: the samples west of the flight's ``SEEN`` quantile of
    x (the held-out part, east of it, is a region the seen part never flew over)."""
    x = positions_local(trace, frame.to_local)[:, 0]
    return np.asarray(x < np.quantile(x, SEEN))


@dataclass(frozen=True)
class Row:
    label: str
    split: str
    rmse_db: float
    bias_db: float
    coverage: float
    errors: dict[str, float | None]
    fit_s: float


REFERENCES = ("ref: free space", "ref: oracle refit")
"""Reference rows of every split: the scenario's free-space model (nothing fitted), and
log-distance refitted on the held-out part itself (a yardstick, not a twin). The noise floor
is a column (over the floor); ``oracle: twin - bias`` is added on synthetic worlds."""

BASELINES = ("twin (DT map)", "log-distance", "ref: free space")
"""The baseline rows a learned twin must not lose to (by more than ``NOT_WORSE_DB``)."""

LEARNED = "neural + DT prior"
NOT_WORSE_DB = 0.3
ORACLE_GAP_DB = 1.5


def snr_scores(
    maps: list[str | Path], scenario: Scenario, held: Path
) -> list[tuple[float, float, float]]:
    """(mean over towers of SNR RMSE, of bias, of 95% coverage) of each map on ``held``."""
    from skymule.radio.radiomap import frame_offset_m, read_radiomap, valid_mask

    frame = LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon)
    names = scenario.signal.sensors_from_trace or [s.name for s in scenario.sensors]
    trace = read_trace(held, sensors=names)
    positions = positions_local(trace, frame.to_local)
    out = []
    for spec in maps:
        if spec == "fspl":
            source = model_source(
                scenario.radio.model_copy(update={"model": "fspl"}),
                sensor_positions_m(scenario.sensors, frame),
            )
            predicted, sigma = np.asarray(source.snr_db(positions)), None
        else:
            fitted = read_radiomap(Path(spec))
            src = fitted.source(names, frame_offset_m(fitted.origin, frame))
            predicted, sigma = src.snr_db(positions), src.sigma_db(positions)
        rmse, bias, cover = [], [], []
        for j in range(len(names)):
            ok, _, _ = valid_mask(trace.snr_db[:, j], -40.0)
            error = predicted[ok, j] - trace.snr_db[ok, j]
            rmse.append(np.sqrt(np.mean(error**2)))
            bias.append(error.mean())
            if sigma is not None:
                cover.append(np.mean(np.abs(error) <= 1.96 * sigma[ok, j]))
        out.append((float(np.mean(rmse)), float(np.mean(bias)),
                    float(np.mean(cover)) if cover else float("nan")))  # fmt: skip
    return out


def noise_floor_db(trace: Trace, window: int = 5) -> float:
    """The trace's own noise: RMS of SNR minus its running median over ``window`` samples,
    mean over towers (an estimate: a real flight's floor is not known)."""
    floors = []
    for j in range(trace.snr_db.shape[1]):
        snr = trace.snr_db[:, j]
        ok = np.isfinite(snr) & (snr > -40.0)
        smooth = running_median(snr[ok], window)
        floors.append(np.sqrt(np.mean((snr[ok] - smooth) ** 2)))
    return float(np.mean(floors))


def evaluate(
    scenario: Scenario, scenario_ref: str, dt: Path, seen: list[Path], held: Path, folder: Path,
    split: str, policies: bool = True,
) -> list[Row]:  # fmt: skip
    """Fit every map of METHODS on ``seen`` (+ the DT), score it on ``held``, with the
    reference rows; each policy's decision regret (its decisions on the map, executed on the
    held-out trace, against its decisions there) from sim2real when ``policies`` (a held-out
    part that is one stretch of flight)."""
    maps, fit_s = {}, {}
    for label, method, prior in METHODS:
        out = folder / f"{split.split()[0]}-{label.replace(' ', '_').replace(',', '')}.json"
        traces = [dt] if method == "dt" else [dt, *seen] if method == "kriging+dt" else seen
        start = time.process_time()
        fit = fit_radiomap_files(
            traces,
            scenario=scenario_ref,
            method="kriging" if method in ("dt", "kriging+dt") else method,
            prior=str(dt) if prior == "dt" else None,
        )
        fit_s[label] = time.process_time() - start
        fit.fitted.write(out)
        maps[label] = str(out)
        if label == LEARNED and fit.note:
            print(f"  {split}, {label}: {fit.note}")
    oracle = folder / f"{split.split()[0]}-oracle.json"
    fit_radiomap_files([held], scenario=scenario_ref, method="log-distance").fitted.write(oracle)
    labels = [label for label, _, _ in METHODS] + list(REFERENCES)
    scores = snr_scores([*maps.values(), "fspl", oracle], scenario, held)
    errors: dict[str, dict[str, float | None]] = {k: dict.fromkeys(POLICIES) for k in labels}
    if policies:
        result = sim2real(scenario, held, list(maps.values()), list(POLICIES))
        for label, twin in zip(maps, result.twins, strict=True):
            errors[label] = {p: twin.policies[p]["regret"] for p in POLICIES}  # type: ignore[misc]
    return [
        Row(label, split, rmse, bias, cover, errors[label], fit_s.get(label, 0.0))
        for label, (rmse, bias, cover) in zip(labels, scores, strict=True)
    ]


ORACLE = "oracle: twin - bias"
"""A reference row: the twin with its true per-tower bias subtracted, i.e. everything the twin
knows, perfectly calibrated; what no map learned from the seen data can be expected to beat
much where the real flight goes somewhere new."""


def oracle_row(world: World, scenario: Scenario, held: Path, split: str) -> Row:
    trace = read_trace(held)
    frame = LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon)
    positions = positions_local(trace, frame.to_local)
    error = world.twin_db(positions) - world.bias_db - trace.snr_db
    rmse = float(np.mean(np.sqrt(np.mean(error**2, axis=0))))
    return Row(ORACLE, split, rmse, float(error.mean()), float("nan"),
               dict.fromkeys(POLICIES), 0.0)  # fmt: skip


COLUMNS = [
    "map", "held out", "SNR RMSE [dB]", "over the noise floor [dB]", "bias [dB]",
    "in the 95% interval", "Greedy regret", "HGAD regret", "fit CPU [s]",
]  # fmt: skip


def cells(r: Row, floor_db: float | None) -> list[str]:
    """One row's cells, as printed and as written by --json (same decimals down a column)."""
    errors = [
        "n/a" if r.errors[p] is None else f"{100 * r.errors[p]:+.1f}%"  # type: ignore[operator]
        for p in POLICIES
    ]
    return [
        r.label, r.split, f"{r.rmse_db:.2f}",
        f"{r.rmse_db - floor_db:+.2f}" if floor_db is not None else "n/a",
        f"{r.bias_db:+.1f}", "n/a" if np.isnan(r.coverage) else f"{100 * r.coverage:.0f}%",
        *errors, f"{r.fit_s:.1f}",
    ]  # fmt: skip


def print_rows(title: str, rows: list[Row], floor_db: float | None) -> None:
    print(title)
    head = f"  {'map':<20} {'split':<16} {'SNR RMSE':>9} {'- floor':>8} {'bias':>6}"
    print(head + f" {'in 95%':>7} {'greedy reg':>11} {'hgad reg':>9} {'fit CPU s':>10}")
    for r in rows:
        c = cells(r, floor_db)
        print(
            f"  {c[0]:<20} {c[1]:<16} {c[2]:>9} {c[3]:>8} {c[4]:>6} {c[5]:>7} {c[6]:>11} "
            f"{c[7]:>9} {c[8]:>10}"
        )


def mean_rows(rows: list[Row]) -> list[Row]:
    """Per (map, split), the mean over worlds (decision regret too)."""
    out = []
    for split in dict.fromkeys(r.split for r in rows):
        for label in dict.fromkeys(r.label for r in rows):
            group = [r for r in rows if r.label == label and r.split == split]
            if not group:
                continue
            errors: dict[str, float | None] = {
                p: float(np.mean(seen)) if seen else None
                for p in POLICIES
                for seen in [[r.errors[p] for r in group if r.errors[p] is not None]]
            }
            out.append(
                Row(label, split, float(np.mean([r.rmse_db for r in group])),
                    float(np.mean([r.bias_db for r in group])),
                    float(np.mean([r.coverage for r in group])), errors,
                    float(np.mean([r.fit_s for r in group])))
            )  # fmt: skip
    return out


def verdicts(rows: list[Row]) -> list[str]:
    """One line per split: the learned twin against the best baseline row and the oracle
    refit, and its 95% coverage, each with the target and met/missed."""
    lines = []
    for split in dict.fromkeys(r.split for r in rows):
        by = {r.label: r for r in rows if r.split == split}
        if LEARNED not in by:
            continue
        learned = by[LEARNED]
        best = min((by[b] for b in BASELINES if b in by), key=lambda r: r.rmse_db)
        oracle = by["ref: oracle refit"]
        gap_best = learned.rmse_db - best.rmse_db
        gap_oracle = learned.rmse_db - oracle.rmse_db
        cover = learned.coverage
        lines.append(
            f"{split}: learned twin {learned.rmse_db:.2f} dB; best baseline ({best.label}) "
            f"{best.rmse_db:.2f} dB: {gap_best:+.2f} dB (target <= +{NOT_WORSE_DB:g}: "
            f"{'met' if gap_best <= NOT_WORSE_DB else 'MISSED'}); oracle refit "
            f"{oracle.rmse_db:.2f} dB: {gap_oracle:+.2f} dB (target <= +{ORACLE_GAP_DB:g}: "
            f"{'met' if gap_oracle <= ORACLE_GAP_DB else 'MISSED'}); in the 95% interval "
            f"{100 * cover:.0f}% (target 85-99%: {'met' if 0.85 <= cover <= 0.99 else 'MISSED'})"
        )
    return lines


def write_json(path: Path, rows: list[Row], floor_db: float | None, note: str) -> None:
    """``{"tables": {"sim2real": {"columns", "rows", "note"}}}`` for the README renderer."""
    from _results import table, write

    cells_ = [cells(r, floor_db) for r in rows]
    write(path, {"sim2real": table(COLUMNS, cells_, note, align="llrrrrrrr")})


def synthetic(worlds: int, json_path: Path | None) -> None:
    scenario = load_scenario(BASE, [f"sensors[{i}].buffer_mbit={b}" for i, b in
                                    enumerate(BUFFERS_MBIT)])  # fmt: skip
    frame = LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon)
    print(
        f"synthetic worlds: noise floor {NOISE_DB:g} dB; twin smoother ({TWIN_SMOOTHING_M:g} m) "
        f"and optimistic ({TWIN_BIAS_DB[0]:g}-{TWIN_BIAS_DB[1]:g} dB); {SECONDS} s flights; "
        f"seen: the DT flight + the first {SEEN:.0%} of real flight B (time) or its west "
        f"{SEEN:.0%} (region)"
    )
    everything = []
    for seed in range(worlds):
        world = draw_world(seed, scenario)
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            paths = write_flights(world, scenario, folder, seed)
            real_b = read_trace(paths["real_b"])
            rows: list[Row] = []
            for split, seen_mask, policies in (
                ("region (east 60%)", split_region(real_b, frame), False),
                ("time (last 60%)", split_time(real_b), True),
            ):
                seen = write_part(real_b, seen_mask, folder / "seen.csv")
                held = write_part(real_b, ~seen_mask, folder / "held.csv")
                rows += evaluate(scenario, BASE, paths["dt"], [seen], held, folder, split,
                                 policies)  # fmt: skip
                rows.append(oracle_row(world, scenario, held, split))
            if not tiny():
                flight_split = "flight (A -> B)"
                rows += evaluate(
                    scenario, BASE, paths["dt"], [paths["real_a"]], paths["real_b"], folder,
                    flight_split,
                )  # fmt: skip
                rows.append(oracle_row(world, scenario, paths["real_b"], flight_split))
        print_rows(f"world {seed}", rows, NOISE_DB)
        everything += rows
    means = mean_rows(everything)
    print_rows(f"mean over {worlds} worlds (decision regret: mean)", means, NOISE_DB)
    best = next(r for r in means if r.label == LEARNED and r.split.startswith("time"))
    print(
        f"learned twin ({LEARNED}), time split: RMSE {best.rmse_db:.2f} dB, "
        f"{best.rmse_db - NOISE_DB:+.2f} dB over the noise floor"
    )
    for line in verdicts(means):
        print(line)
    if json_path is not None:
        note = (
            f"Mean over {worlds} synthetic worlds (benchmarks/bench_sim2real.py): every map sees "
            f"the DT flight and the seen part of real flight B (region: its west {SEEN:.0%}; "
            f"time: its first {SEEN:.0%}; flight: all of flight A) and is scored on the rest. "
            f"Noise floor {NOISE_DB:g} dB. 'ref:' rows are references, not twins: free space "
            "(nothing fitted) and log-distance refitted on the held-out part itself."
        )
        write_json(json_path, means, NOISE_DB, note)


def fit_time() -> None:
    """CPU seconds of one learned-twin fit on a few thousand samples per sensor."""
    scenario = load_scenario(BASE)
    world = draw_world(0, scenario)
    n = size(3000, 200)
    with tempfile.TemporaryDirectory() as tmp:
        rng = np.random.default_rng(3)
        xyz = np.column_stack([rng.uniform(-400, 400, n), rng.uniform(-550, 300, n),
                               rng.uniform(20, 60, n)])  # fmt: skip
        order = np.argsort(xyz[:, 1])  # a slow sweep north to south: samples in time order
        xyz = xyz[order]
        names = [s.name for s in scenario.sensors]
        snr = world.truth_db(xyz) + NOISE_DB * rng.standard_normal((n, len(names)))
        path = write_dt_export(Path(tmp) / "big.csv", np.arange(n, dtype=float), snr, names,
                               xyz[:, 0], xyz[:, 1], xyz[:, 2])  # fmt: skip
        twin = world.twin_db(xyz)
        dt = write_dt_export(Path(tmp) / "dt.csv", np.arange(n, dtype=float), twin, names,
                             xyz[:, 0], xyz[:, 1], xyz[:, 2])  # fmt: skip
        start, wall = time.process_time(), time.perf_counter()
        fit_radiomap_files([path], scenario=BASE, method="neural", prior=str(dt))
        cpu, wall = time.process_time() - start, time.perf_counter() - wall
    load = os.getloadavg()[0]
    print(f"fit time, neural + prior, {n:,} samples x {len(names)} sensors: {cpu:.1f} s CPU, "
          f"{wall:.1f} s wall at load {load:.1f} (target < 60 s on 2 cores)")  # fmt: skip


def real_pair(dt: Path, real: Path, scenario_ref: str | None, json_path: Path | None) -> None:
    ref = scenario_ref or BASE
    scenario = load_scenario(ref)
    frame = LocalFrame(scenario.site.origin.lat, scenario.site.origin.lon)
    trace = read_trace(real)
    floor = noise_floor_db(trace)
    print(
        f"real pair: DT {dt}, real {real}; seen: the DT flight + the first {SEEN:.0%} of the "
        f"real flight (time) or its west {SEEN:.0%} (region); noise floor (SNR minus its "
        f"5-sample running median) {floor:.2f} dB"
    )
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for split, seen_mask, policies in (
            ("region (east 60%)", split_region(trace, frame), False),
            ("time (last 60%)", split_time(trace), True),
        ):
            seen = write_part(trace, seen_mask, folder / f"seen{real.suffix}")
            held = write_part(trace, ~seen_mask, folder / f"held{real.suffix}")
            rows += evaluate(scenario, ref, dt, [seen], held, folder, split, policies)
    print_rows("measured on your flights", rows, floor)
    for line in verdicts(rows):
        print(line)
    if json_path is not None:
        note = (
            f"Measured on {real.name} with its twin {dt.name}: every map sees the DT flight "
            f"and the seen part of the real flight, and is scored on the rest. Noise floor "
            f"estimated as SNR minus its 5-sample running median: {floor:.2f} dB."
        )
        write_json(json_path, rows, floor, note)


def library_comparison() -> None:
    """skymule's kriging (variogram by weighted least squares, simple kriging in numpy, what
    a map file holds) against scikit-learn's GaussianProcessRegressor (the same exponential
    kernel + nugget by maximum likelihood, its own predictor): held-out RMSE and 95% coverage
    of the residual over the log-distance trend, time split, every tower of 3 worlds."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    from skymule.radio.kriging import fit_variogram, krige, kriging_weights, thin_indices
    from skymule.radio.radiomap import SensorMap, distance_m, fit_trend, trend_db

    scenario = load_scenario(BASE)
    results: dict[str, list[tuple[float, float]]] = {"skymule kriging": [], "sklearn GPR": []}
    cpu = dict.fromkeys(results, 0.0)
    for seed in range(size(3, 1)):
        world = draw_world(seed, scenario)
        rng = np.random.default_rng(11 + seed)
        xyz = fly(scenario, 9.0, (0.0, 0.0))
        snr = world.truth_db(xyz) + NOISE_DB * rng.standard_normal((len(xyz), 4))
        cut = int(SEEN * len(xyz))
        for j, tower in enumerate(world.sensor_m):
            seen, held = xyz[:cut], xyz[cut:]
            a, n = fit_trend(distance_m(seen, tower), snr[:cut, j])
            residual = snr[:cut, j] - trend_db(seen, tower, a, n)
            target = snr[cut:, j] - trend_db(held, tower, a, n)
            with threadpool_limits(1, user_api="blas"):
                start = time.process_time()
                keep = thin_indices(cut, 1000)
                vario = fit_variogram(seen[keep], residual[keep])
                weights = kriging_weights(seen[keep], residual[keep], vario)
                fitted = SensorMap("x", tower, a, n, vario, seen[keep], weights)
                ours = krige(held, seen[keep], weights, vario)
                ours_sd = fitted.sigma_db(held)
                cpu["skymule kriging"] += time.process_time() - start
                start = time.process_time()
                var = float(np.var(residual))
                kernel = ConstantKernel(var) * Matern(50.0, (1.0, 1e5), nu=0.5) + WhiteKernel(
                    var / 2
                )
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    gpr = GaussianProcessRegressor(kernel, n_restarts_optimizer=2, random_state=0)
                    gpr.fit(seen[keep], residual[keep])
                theirs, theirs_sd = gpr.predict(held, return_std=True)
                cpu["sklearn GPR"] += time.process_time() - start
            for key, mean, sd in (("skymule kriging", ours, ours_sd),
                                  ("sklearn GPR", theirs, theirs_sd)):  # fmt: skip
                error = mean - target
                results[key].append(
                    (float(np.sqrt(np.mean(error**2))), float(np.mean(np.abs(error) <= 1.96 * sd)))
                )
    print(f"library comparison: residual over the log-distance trend, time split, "
          f"{len(results['sklearn GPR'])} tower-worlds")  # fmt: skip
    for key, rows in results.items():
        rmse, cover = np.mean(rows, axis=0)
        print(f"  {key:<16} held-out RMSE {rmse:.2f} dB, in the 95% interval "
              f"{100 * cover:.0f}%, fit + predict {cpu[key]:.1f} s CPU")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--worlds", type=int, default=size(3, 1))
    parser.add_argument("--dt", type=Path, help="a digital twin's flight (DT export / log)")
    parser.add_argument("--real", type=Path, help="a real flight (merged log)")
    parser.add_argument("--scenario", help="sensors and positions (default paper-sim-fixed)")
    parser.add_argument(
        "--libraries", action="store_true", help="skymule's kriging vs scikit-learn's GP"
    )
    parser.add_argument("--json", type=Path, help="also write the table as JSON (README)")
    args = parser.parse_args()
    if (args.dt is None) != (args.real is None):
        parser.error("give both --dt and --real (or neither, for the synthetic worlds)")
    if args.dt is not None:
        real_pair(args.dt, args.real, args.scenario, args.json)
        return
    if args.libraries:
        library_comparison()
        return
    synthetic(args.worlds, args.json)
    fit_time()


if __name__ == "__main__":
    main()
