"""Write the synthetic sample flights in examples/samples/ (deterministic: same files every run).

Run from the repository root: ``python scripts/make_samples.py [--out examples/samples]``.

The model (examples/samples/README.md says the same for users):

* Site, towers and link budget: the ``paper-sim-fixed`` preset (Lake Wheeler towers LW1..LW4,
  free space at 3.41 GHz, 10 dBm, 10 + 2 dBi, -90 dBm noise, 1.4 MHz, AADM LTE CQI table), its
  lawnmower path inside the geofence at 30 m and 10 m/s, one sample a second.
* Digital twin (``dt_flight.csv``): the first ``DT_SECONDS`` of that path, SNR from the two-ray
  ground-reflection model (``DT_MODEL``: a twin's idealised propagation, no clutter, no fading),
  ``DT_MISSING_SHARE`` of the cells dropped to -99 (missing).
* "Real" flight (``flight_merged.csv``): the first ``FLIGHT_SECONDS`` of the same path, SNR from
  free space + spatially correlated log-normal shadowing (``SHADOWING_STD_DB``, decorrelation
  ``SHADOWING_DECORRELATION_M``) + per-second Rician fading (K = ``RICIAN_K_DB``), all drawn by
  skymule's own channel code from the scenario seed ``SEED``; polls ``POLL_JITTER_S`` late at most.
* Second "real" flight (``flight2_merged.csv``): the same towers on another day, the same
  route at ``FLIGHT2_SPEED_MPS`` for ``FLIGHT2_SECONDS``, the same terrain (the shadowing field
  of ``SEED``) and new Rician fading draws; for ``sim2real`` (learn on one flight, check on
  the other).
* Volumes (``volumes.txt``): the paper's Flight 1 buffers, 500/800/700/1000 Mbit, tower 1 first.
* The flight's own downloads: Greedy (serve the highest SNR with data left) replayed on the
  "real" flight with those volumes, at ``GOODPUT`` of the rate table's rate (protocol
  overhead), written twice: ``flight_downloads.csv`` in the AADM controller's format
  (``time,dl_lw1..dl_lw4``: cumulative Mbit per tower at every poll, the poll's row including
  the second it opens) and ``flight_downloads_tower.csv`` in skymule's ``time,tower,mbit``
  format (one row per second with a download).
"""

from __future__ import annotations

import argparse
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd

from skymule.io.traces import read_trace, write_aadm_log, write_dt_export
from skymule.radio.fading import draw_fading_db
from skymule.scenario import Scenario, load_scenario
from skymule.tasks.analyze import analysis_scenario
from skymule.tasks.simulate import simulate
from skymule.units import BITS_PER_MBIT
from skymule.world import build_mission

SEED = 2025
DT_MODEL = "two-ray"
DT_SECONDS = 360
FLIGHT_SECONDS = 360
DT_MISSING_SHARE = 0.01
SHADOWING_STD_DB = 4.0
SHADOWING_DECORRELATION_M = 30.0
RICIAN_K_DB = 6.0
POLL_JITTER_S = 0.012
FLIGHT2_SECONDS = 360
FLIGHT2_SPEED_MPS = 9.0
FLIGHT2_START = "2025-05-27 10:02:11.402"
VOLUMES_MBIT = (500.0, 800.0, 700.0, 1000.0)
GOODPUT = 0.9
START = "2025-05-24 16:19:31.186"
TIME_FORMAT = "%Y-%m-%d %H:%M:%S.%f"
OUT = Path(__file__).resolve().parents[1] / "examples" / "samples"


def _radio_scenario(model: str, shadowing_db: float, fading: str, duration_s: int) -> Scenario:
    """paper-sim-fixed with the sample's channel, length and seed."""
    base = load_scenario("paper-sim-fixed")
    radio = base.radio.model_copy(
        update={
            "model": model,
            "shadowing_std_db": shadowing_db,
            "shadowing_decorrelation_m": SHADOWING_DECORRELATION_M,
            "fading": fading,
            "rician_k_db": RICIAN_K_DB,
        }
    )
    mission = base.mission.model_copy(update={"duration_s": float(duration_s)})
    return base.model_copy(update={"radio": radio, "mission": mission, "seed": SEED})


def write_digital_twin(path: Path) -> None:
    """The digital-twin export: two-ray SNR, a few cells missing (-99)."""
    mission = build_mission(_radio_scenario(DT_MODEL, 0.0, "none", DT_SECONDS))
    assert mission.track is not None
    xyz = mission.track.position_m[:DT_SECONDS]
    snr = mission.track.snr_db[:DT_SECONDS].round(2)
    rng = np.random.default_rng([SEED, 1])
    snr[rng.random(snr.shape) < DT_MISSING_SHARE] = np.nan  # written as -99
    time_s = np.arange(len(xyz), dtype=float)
    names = mission.sensor_names
    write_dt_export(path, time_s, snr, names, xyz[:, 0].round(2), xyz[:, 1].round(2), xyz[:, 2])


def write_flight(path: Path) -> None:
    """The AADM merged log: free space + shadowing + Rician fading, polls a little late."""
    mission = build_mission(_radio_scenario("fspl", SHADOWING_STD_DB, "rician", FLIGHT_SECONDS))
    assert mission.track is not None and mission.fading_db is not None
    xyz = mission.track.position_m[:FLIGHT_SECONDS]
    snr = (mission.track.snr_db[:FLIGHT_SECONDS] + mission.fading_db[:FLIGHT_SECONDS]).round(2)
    rng = np.random.default_rng([SEED, 2])
    jitter_s = rng.uniform(0.0, POLL_JITTER_S, len(xyz))
    jitter_s[0] = 0.0  # the first poll is the log's start
    time_s = np.arange(len(xyz)) + jitter_s
    lat, lon = mission.frame.to_latlon(xyz[:, 0], xyz[:, 1])
    write_aadm_log(
        path, time_s, snr, mission.sensor_names, lat.round(7), lon.round(7), xyz[:, 2], start=START
    )


def write_second_flight(path: Path) -> None:
    """A second "real" flight of the same towers on another day: the same route at
    ``FLIGHT2_SPEED_MPS``, the same terrain (the shadowing field of ``SEED``), new fading."""
    scenario = _radio_scenario("fspl", SHADOWING_STD_DB, "rician", FLIGHT2_SECONDS)
    trajectory = scenario.trajectory.model_copy(update={"speed_mps": FLIGHT2_SPEED_MPS})
    mission = build_mission(scenario.model_copy(update={"trajectory": trajectory}))
    assert mission.track is not None
    xyz = mission.track.position_m[:FLIGHT2_SECONDS]
    fading = draw_fading_db(scenario.radio, np.random.default_rng([SEED, 3]), len(xyz), 4)
    assert fading is not None
    snr = (mission.track.snr_db[:FLIGHT2_SECONDS] + fading).round(2)
    rng = np.random.default_rng([SEED, 4])
    jitter_s = rng.uniform(0.0, POLL_JITTER_S, len(xyz))
    jitter_s[0] = 0.0
    lat, lon = mission.frame.to_latlon(xyz[:, 0], xyz[:, 1])
    write_aadm_log(
        path, np.arange(len(xyz)) + jitter_s, snr, mission.sensor_names, lat.round(7),
        lon.round(7), xyz[:, 2], start=FLIGHT2_START,
    )  # fmt: skip


def write_downloads(flight: Path, controller: Path, towers: Path) -> None:
    """The flight's own download log, in the AADM controller's and in skymule's format."""
    trace = read_trace(flight)
    result = simulate(analysis_scenario(trace, flight, list(VOLUMES_MBIT)), "greedy")
    log = result.log
    got_mbit = log.downloaded_bit * GOODPUT / BITS_PER_MBIT
    names = [name.lower() for name in result.mission.sensor_names]
    start = datetime.fromisoformat(START)
    stamps = [
        (start + timedelta(seconds=float(t))).strftime(TIME_FORMAT)[:-3]
        for t in trace.time_s[: log.n_slots]
    ]
    per_tower = np.zeros((log.n_slots, len(names)))
    served = log.served >= 0
    per_tower[np.flatnonzero(served), log.served[served]] = got_mbit[served]
    cumulative = pd.DataFrame(per_tower.cumsum(axis=0).round(3), columns=[f"dl_{n}" for n in names])
    cumulative.insert(0, "time", stamps)
    cumulative.to_csv(controller, index=False)
    rows = pd.DataFrame(
        {
            "time": [stamps[t] for t in np.flatnonzero(served)],
            "tower": [result.mission.sensor_names[i] for i in log.served[served]],
            "mbit": got_mbit[served].round(3),
        }
    )
    rows[rows["mbit"] > 0].to_csv(towers, index=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--out", type=Path, default=OUT, help="folder to write (default: %(default)s)"
    )
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    write_digital_twin(out / "dt_flight.csv")
    write_flight(out / "flight_merged.csv")
    write_second_flight(out / "flight2_merged.csv")
    (out / "volumes.txt").write_text("".join(f"{v:g}\n" for v in VOLUMES_MBIT))
    write_downloads(
        out / "flight_merged.csv", out / "flight_downloads.csv", out / "flight_downloads_tower.csv"
    )
    for path in [*sorted(out.glob("*.csv")), out / "volumes.txt"]:
        print(f"{path}: {path.stat().st_size / 1e3:.1f} kB")


if __name__ == "__main__":
    main()
