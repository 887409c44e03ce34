"""Channel throughput: SNR for 4 sensors x 100,000 positions, each path-loss model, with
shadowing, and radio-map queries (fast path and dense reference). Prints wall-clock
seconds (best of 3).

    python benchmarks/bench_channel.py [--json PATH]
    (SKYMULE_BENCH_TINY=1: 2,000 positions, 1 run)

``--json benchmarks/results/channel.json``: the speed table's SNR row (docs/speed.md).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.geo import LocalFrame, sensor_positions_m
from skymule.radio.channel import signal_source
from skymule.radio.kriging import krige_dense
from skymule.radio.pathloss import PATHLOSS_MODELS
from skymule.radio.radiomap import RadioMap, SensorSamples, fit_sensor_map
from skymule.scenario import load_scenario

N_POSITIONS = size(100_000, 2_000)
REPEATS = size(3, 1)
N_TRAIN = size(1000, 200)


def best_of(fn, repeats: int = REPEATS) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main(json_path: Path | None = None) -> None:
    base = load_scenario("aadm-default")
    frame = LocalFrame(base.site.origin.lat, base.site.origin.lon)
    sensor_m = sensor_positions_m(base.sensors, frame)
    rng = np.random.default_rng(0)
    positions = np.column_stack(
        [rng.uniform(-400, 400, N_POSITIONS), rng.uniform(-550, 300, N_POSITIONS),
         np.full(N_POSITIONS, 30.0)]
    )  # fmt: skip
    print(f"SNR for {len(sensor_m)} sensors x {N_POSITIONS:,} positions [s, best of {REPEATS}]")
    seconds = {}
    for name in PATHLOSS_MODELS.names():
        scenario = base.model_copy(update={"radio": base.radio.model_copy(update={"model": name})})
        source = signal_source(scenario, frame, sensor_m)
        seconds[name] = best_of(lambda s=source: s.snr_db(positions))
        print(f"  {name:<14} {seconds[name]:.3f}")
    shadowed = base.model_copy(
        update={"radio": base.radio.model_copy(update={"shadowing_std_db": 6.0})}
    )
    build = best_of(lambda: signal_source(shadowed, frame, sensor_m))
    source = signal_source(shadowed, frame, sensor_m)
    query = best_of(lambda: source.snr_db(positions))
    print(
        f"  fspl + shadowing: field draw {build:.3f}, query {query:.3f}, total {build + query:.3f}"
    )
    # radio map: 1000 training samples per sensor (the kriging cap)
    train = positions[:N_TRAIN]
    snr = source.snr_db(train)
    segment = np.arange(N_TRAIN) * 5 // N_TRAIN
    fit = best_of(
        lambda: fit_sensor_map("LW1", sensor_m[0], SensorSamples(train, snr[:, 0], segment)), 1
    )
    print(f"  radio map: fit 1 sensor x {N_TRAIN} samples (+5-fold CV) {fit:.3f}")
    names = [s.name for s in base.sensors]
    fitted = RadioMap(
        (frame.origin_lat_deg, frame.origin_lon_deg),
        tuple(
            fit_sensor_map(name, sensor_m[j], SensorSamples(train, snr[:, j], segment))
            for j, name in enumerate(names)
        ),
    )
    map_source = fitted.source(names)
    query_map = best_of(lambda: map_source.snr_db(positions))
    n = len(names)
    print(f"  radio map: query {n} sensors x {N_POSITIONS:,} positions {query_map:.3f}")
    dense = best_of(lambda: dense_snr_db(fitted.sensors, positions), 1)
    error = np.abs(map_source.snr_db(positions) - dense_snr_db(fitted.sensors, positions)).max()
    print(
        f"  radio map: dense reference {n} sensors x {N_POSITIONS:,} positions {dense:.3f} "
        f"(max |fast - dense| {error:.1e} dB)"
    )
    row = [
        f"SNR, {len(sensor_m)} sensors × {N_POSITIONS:,} positions, fspl + shadowing",
        f"{build + query:.2f} s (field draw {build:.2f} s + query {query:.2f} s); "
        f"fspl alone {seconds['fspl']:.2f} s",
        "`python benchmarks/bench_channel.py`",
    ]
    write(json_path, {"speed-channel": table(["what", "figure", "command"], [row], align="lll")})


def dense_snr_db(maps, positions: np.ndarray) -> np.ndarray:
    """(P, N) SNR [dB] with every query against every kriging sample (reference path)."""
    return np.column_stack(
        [m.trend_db(positions) + krige_dense(positions, m.train_m, m.weights, m.variogram)
         for m in maps]
    )  # fmt: skip


if __name__ == "__main__":
    main(json_option())
