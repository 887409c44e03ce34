"""The shipped sample flights: readable, as documented, and what scripts/make_samples.py makes."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from skymule.io.traces import read_trace, read_volumes

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "examples" / "samples"
FILES = (
    "dt_flight.csv",
    "flight_merged.csv",
    "flight2_merged.csv",
    "flight_downloads.csv",
    "flight_downloads_tower.csv",
    "volumes.txt",
)


def test_samples_are_small_and_in_their_formats() -> None:
    for name in FILES:
        assert (SAMPLES / name).stat().st_size < 100_000, name
    flight = read_trace(SAMPLES / "flight_merged.csv")
    twin = read_trace(SAMPLES / "dt_flight.csv")
    assert flight.columns == twin.columns == ("LW1", "LW2", "LW3", "LW4")
    assert flight.n_samples == twin.n_samples == 360
    second = read_trace(SAMPLES / "flight2_merged.csv")
    assert second.columns == flight.columns and second.n_samples == 360
    # another day on the same route: slower, so it covers less ground in the same time
    step = np.linalg.norm(np.diff(np.c_[second.lat_deg, second.lon_deg], axis=0), axis=1)
    first_step = np.linalg.norm(np.diff(np.c_[flight.lat_deg, flight.lon_deg], axis=0), axis=1)
    assert np.median(step) < np.median(first_step)
    assert np.allclose(np.diff(flight.time_s), 1.0, atol=0.02)  # one poll a second
    assert np.isnan(twin.snr_db).any() and not np.isnan(flight.snr_db).any()
    assert read_volumes(SAMPLES / "volumes.txt").tolist() == [500, 800, 700, 1000]
    controller = pd.read_csv(SAMPLES / "flight_downloads.csv")
    assert list(controller.columns) == ["time", "dl_lw1", "dl_lw2", "dl_lw3", "dl_lw4"]
    assert len(controller) == flight.n_samples
    cumulative = controller.iloc[:, 1:].to_numpy()
    assert (np.diff(cumulative, axis=0) >= 0).all()
    assert (cumulative[-1] <= [500, 800, 700, 1000]).all()
    rows = pd.read_csv(SAMPLES / "flight_downloads_tower.csv")
    per_tower = rows.groupby("tower")["mbit"].sum()
    # both download logs tell the same story
    assert np.allclose([per_tower.get(f"LW{i}", 0.0) for i in range(1, 5)], cumulative[-1])


def test_make_samples_reproduces_the_shipped_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys, "argv", ["make_samples.py", "--out", str(tmp_path)])
    runpy.run_path(str(ROOT / "scripts" / "make_samples.py"), run_name="__main__")
    for name in FILES:
        assert (tmp_path / name).read_bytes() == (SAMPLES / name).read_bytes(), name
