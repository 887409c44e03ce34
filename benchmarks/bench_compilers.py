"""Which compiler for the batched slot loop: numba vs JAX on Greedy (why skymule[fast] is numba).

Run: /work/venv/bin/python benchmarks/bench_compilers.py [n_missions]
(needs numba and ``jax[cpu]``; neither is a dependency of skymule's core).

Same work for both: paper-sim-fixed (4 sensors, 500 slots), random buffers, Greedy, the
per-slot logs the summaries need. numba: skymule's compiled loop (one mission at a time, all
its slots in registers). JAX: the natural formulation, ``lax.scan`` over slots with every step
vectorised over missions, jitted (XLA, CPU). Prints mission-slots per CPU-second (best of 3,
compile excluded) and checks both download the same bits per mission.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.policies import Greedy
from skymule.scenario import load_scenario
from skymule.sim.fixed import stack_tracks
from skymule.sim.run import run_missions
from skymule.world import build_mission


def jax_greedy(rate: np.ndarray, snr: np.ndarray, buffers: np.ndarray, dt: float):  # type: ignore[no-untyped-def]
    """Greedy on one shared track: rate/snr (T, N), buffers (B, N) -> downloaded (B, T)."""
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)

    def step(remaining, observed):  # type: ignore[no-untyped-def]
        rate_t, snr_t = observed
        has_data = remaining > 0
        masked = jnp.where(has_data, snr_t[None, :], -jnp.inf)
        choice = jnp.argmax(masked, axis=1)  # first maximum: ties to the lowest index
        any_data = has_data.any(axis=1)
        onehot = jax.nn.one_hot(choice, remaining.shape[1], dtype=bool) & any_data[:, None]
        left = jnp.take_along_axis(remaining, choice[:, None], axis=1)[:, 0]
        bits = jnp.where(any_data, jnp.minimum(rate_t[choice] * dt, left), 0.0)
        return remaining - jnp.where(onehot, bits[:, None], 0.0), (choice, bits)

    run = jax.jit(lambda r, s, q: jax.lax.scan(step, q, (r, s)))
    return run, (jnp.asarray(rate), jnp.asarray(snr), jnp.asarray(buffers))


def best_cpu(run, repeats: int = 3) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return min(times)


def main(n_missions: int = size(2000, 10), json_path: Path | None = None) -> None:
    base = build_mission(load_scenario("paper-sim-fixed"))
    rng = np.random.default_rng(0)
    missions = [
        replace(base, buffers_bit=rng.uniform(200e6, 1500e6, base.n_sensors))
        for _ in range(n_missions)
    ]
    slots = n_missions * base.n_slots
    columns = ["compiler", "mission-slots per CPU-s [M]", "same bits as numba"]
    if importlib.util.find_spec("numba") is None:
        print("  numba not installed (pip install skymule[fast]): comparison skipped")
        write(json_path, {"compilers": table(columns, [])})
        return
    result = run_missions(missions, Greedy(), detail=False, engine="compiled")
    numba_s = best_cpu(lambda: run_missions(missions, Greedy(), detail=False, engine="compiled"))
    print(f"Greedy, {n_missions} missions x {base.n_slots} slots x {base.n_sensors} sensors")
    print(f"  numba (skymule compiled loop): {slots / numba_s / 1e6:7.1f} M mission-slots/CPU-s")
    rows = [["numba (skymule compiled loop)", f"{slots / numba_s / 1e6:.1f}", "true"]]
    if importlib.util.find_spec("jax") is None:
        print("  JAX   not installed (pip install jax): comparison skipped")
        write(json_path, {"compilers": table(columns, rows)})
        return
    # the track holds at its last sample: the slot-t sample is min(t, K - 1)
    tables = stack_tracks(missions)
    index = np.minimum(np.arange(base.n_slots), tables.n_samples[0] - 1)
    rate, snr = tables.rate_bps[0, index], tables.snr_seen_db[0, index]
    buffers = np.array([m.buffers_bit for m in missions])
    run, args = jax_greedy(rate, snr, buffers, float(base.slot_s))
    _, (_, bits) = run(*args)
    bits.block_until_ready()
    jax_s = best_cpu(lambda: run(*args)[1][1].block_until_ready())
    same = np.array_equal(np.ascontiguousarray(np.asarray(bits).T), result.downloaded_bit)
    print(f"  JAX   (lax.scan over slots):   {slots / jax_s / 1e6:7.1f} M mission-slots/CPU-s")
    print(f"  same bits in every mission-slot: {same}")
    rows.append(["JAX (lax.scan over slots)", f"{slots / jax_s / 1e6:.1f}", str(same).lower()])
    write(json_path, {"compilers": table(columns, rows)})


if __name__ == "__main__":
    json_path = json_option()
    main(int(sys.argv[1]) if len(sys.argv) > 1 else size(2000, 10), json_path=json_path)
