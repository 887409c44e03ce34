"""Radio maps fitted to synthetic flights with known parameters; CLI fit/score/compare."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli
from skymule.geo import LocalFrame
from skymule.io.traces import write_dt_export
from skymule.radio import kriging
from skymule.radio.kriging import (
    Variogram,
    far_kernel,
    krige,
    krige_dense,
    krige_split,
    kriging_weights,
    near_kernel,
    split_error_bound_db,
)
from skymule.radio.radiomap import fit_radiomap, read_radiomap
from skymule.radio.shadowing import shadowing_field
from skymule.radio.sources import model_source
from skymule.scenario import RadioSpec
from skymule.tasks.radiomaps import fit_warnings

ROOT = Path(__file__).parents[1]
FRAME = LocalFrame(35.7274824, -78.6962749)
SENSORS = np.array([[0.0, 100.0, 10.0], [250.0, -200.0, 5.0]])
EXPONENT, SIGMA_DB, D_CORR_M = 2.5, 4.0, 60.0


def _lawnmower() -> np.ndarray:
    legs = []
    for i in range(8):
        xs = np.arange(0.0, 1000.0, 12.5)[:: -1 if i % 2 else 1] - 500.0
        legs.append(
            np.column_stack([xs, np.full(xs.size, -400.0 + 110.0 * i), np.full(xs.size, 30.0)])
        )
    return np.vstack(legs)


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A DT export: SNR = A - 10 n log10 d + Gudmundson shadowing + 0.5 dB noise, 3 % missing."""
    rng = np.random.default_rng(2)
    pos = _lawnmower()
    field = shadowing_field(rng, 2, SIGMA_DB, D_CORR_M, np.array([[-1100, -1100], [1100, 1100]]))
    d = np.linalg.norm(pos[:, None, :] - SENSORS[None], axis=-1)
    snr = np.array([70.0, 65.0]) - 10 * EXPONENT * np.log10(d) + field.at(pos[:, :2])
    snr += 0.5 * rng.standard_normal(snr.shape)
    snr[rng.random(snr.shape) < 0.03] = np.nan
    path = tmp_path_factory.mktemp("rm") / "flight.csv"
    t = np.arange(len(pos), dtype=float)
    write_dt_export(path, t, snr, ["LW1", "LW2"], pos[:, 0], pos[:, 1], pos[:, 2])
    return path


def test_fit_recovers_known_parameters_and_beats_free_space(synthetic: Path) -> None:
    baseline = model_source(RadioSpec(), SENSORS)
    fitted = fit_radiomap([synthetic], ["LW1", "LW2"], SENSORS, FRAME, baseline=baseline)
    for sensor_map, intercept in zip(fitted.sensors, (70.0, 65.0), strict=True):
        # tolerances: one shadowing realisation over ~17 x 13 correlation lengths
        assert sensor_map.exponent == pytest.approx(EXPONENT, abs=0.35)
        # A and n trade off; the trend at a mid-range distance (300 m) is well determined
        at_300 = sensor_map.intercept_db - 10 * sensor_map.exponent * np.log10(300.0)
        assert at_300 == pytest.approx(intercept - 10 * EXPONENT * np.log10(300.0), abs=2.0)
        assert sensor_map.variogram.sill_db2 == pytest.approx(SIGMA_DB**2, rel=0.35)
        assert 0.5 * D_CORR_M < sensor_map.variogram.range_m < 2.0 * D_CORR_M
        stats = sensor_map.stats
        assert stats["n_missing"] > 0 and stats["n_used"] + stats["n_missing"] == 640
        assert stats["rmse_db"] < 1.5  # reproduces the measurements where the UAV flew
        assert stats["cv_rmse_map_db"] < stats["cv_rmse_baseline_db"]  # beats free space
        assert stats["cv_rmse_map_db"] < SIGMA_DB * 1.2
    # far from every measurement the map falls back to its log-distance trend
    far = np.array([[5000.0, 5000.0, 30.0]])
    lw1 = fitted.sensors[0]
    assert lw1.snr_db(far)[0] == pytest.approx(lw1.trend_db(far)[0], abs=1e-6)


def test_cli_fit_score_and_compare_sources(synthetic: Path, tmp_path: Path) -> None:
    scenario = tmp_path / "syn.toml"
    scenario.write_text(
        'name = "syn"\n[mission]\nduration_s = 120\n'
        '[[sensors]]\nname = "LW1"\nx_m = 0.0\ny_m = 100.0\nheight_m = 10.0\nbuffer_mbit = 300\n'
        '[[sensors]]\nname = "LW2"\nx_m = 250.0\ny_m = -200.0\nheight_m = 5.0\nbuffer_mbit = 300\n'
        "[trajectory]\nwaypoints = [[-400, -300, 30], [400, 300, 30]]\n"
    )
    out = tmp_path / "map.json"
    fit = run_cli("fit-radiomap", synthetic, "--out", out, "--scenario", scenario, check=True)
    assert "LW2" in fit.stdout
    assert "warning" not in fit.stderr  # shadowing with structure: a sound fit
    assert read_radiomap(out).names == ("LW1", "LW2")
    scored = run_cli("score-radiomap", out, synthetic, "--json", check=True)
    scores = json.loads(scored.stdout)
    assert set(scores["rmse_db"]) == {"LW1", "LW2"} and max(scores["rmse_db"].values()) < 1.5
    free = json.loads(run_cli("score-radiomap", scenario, synthetic, "--json", check=True).stdout)
    assert free["rmse_db"]["LW1"] > scores["rmse_db"]["LW1"] + 3.0
    assert abs(free["bias_db"]["LW1"]) > 3.0  # the free-space link budget is off
    cmp_dir = tmp_path / "cmp"
    run_cli(
        "compare", scenario, "--sources", f"fspl,radiomap:{out}",
        "--policies", "greedy", "--out", cmp_dir, check=True,
    )  # fmt: skip
    assert (cmp_dir / "snr_cdf_by_source.png").stat().st_size > 1000
    assert (cmp_dir / "fspl" / "greedy" / "summary.json").exists()
    assert len((cmp_dir / "comparison.csv").read_text().splitlines()) == 3


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["fit-radiomap", "tests/fixtures/aadm_merged_small.csv", "--out", "/tmp/x.json"],
         "sensor LW1 has 12 valid SNR samples"),
        (["score-radiomap", "paper-sim-fixed", "tests/fixtures/dt_export_small.csv",
          "--origin", "1,2,3"], "--origin '1,2,3'"),
        (["compare", "paper-sim-fixed", "--sources", "fspl,okumura"], "unknown source 'okumura'"),
    ],
)  # fmt: skip
def test_cli_mistakes_are_one_line(args: list[str], needle: str) -> None:
    done = run_cli(*args, cwd=ROOT)
    assert done.returncode == 2
    assert needle in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_scenario_errors_name_the_field(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(
        '[[sensors]]\nname = "LW1"\nx_m = 0.0\ny_m = 0.0\nbuffer_mbit = 1\n'
        '[mission]\nduration_s = 10\n[radio]\nmodel = "3gpp-uma-av"\n'
        "[trajectory]\nwaypoints = [[0, 0, 15], [100, 0, 15]]\n"
    )
    done = run_cli("run", bad)
    assert done.returncode == 2 and "UAV height 15.0 m is outside the 22.5..300 m" in done.stderr
    bad.write_text(
        '[[sensors]]\nname = "LW1"\nx_m = 0.0\ny_m = 0.0\nbuffer_mbit = 1\n'
        '[signal]\nsource = "radiomap"\n'
    )
    done = run_cli("run", bad)
    assert done.returncode == 2 and "signal" in done.stderr and "map = 'map.json'" in done.stderr


def _synthetic_map() -> tuple[np.ndarray, np.ndarray, Variogram]:
    """Training positions (S, 3), kriging weights (S,) and variogram of a lawnmower flight."""
    rng = np.random.default_rng(5)
    train = _lawnmower()
    field = shadowing_field(rng, 1, SIGMA_DB, D_CORR_M, np.array([[-1100, -1100], [1100, 1100]]))
    residual = field.at(train[:, :2])[:, 0] + 0.5 * rng.standard_normal(len(train))
    vario = Variogram(sill_db2=SIGMA_DB**2, range_m=D_CORR_M, nugget_db2=0.25)
    return train, kriging_weights(train, residual, vario), vario


def test_kernel_split_is_exact_and_smooth() -> None:
    u = np.linspace(0.0, 10.0, 2001)
    near = kriging.SPLIT_NEAR_RANGES
    assert np.allclose(near_kernel(u, near) + far_kernel(u, near), np.exp(-u), atol=1e-15)
    assert np.all(near_kernel(u[u >= near], near) == 0.0)
    # the far part is C^1 across the split radius (no kink for the spline to smear)
    eps = 1e-6
    left, mid, right = far_kernel(np.array([near - eps, near, near + eps]), near)
    assert (mid - left) / eps == pytest.approx((right - mid) / eps, rel=1e-4)


def test_bulk_query_matches_dense_reference() -> None:
    """Split path (exact near field + splined far field) vs every-sample reference.

    Tolerance SPLIT_TOLERANCE_DB = 0.01 dB on the kriged residual (observed 8e-4 dB here);
    queries beyond SPLIT_FAR_RANGES * L get 0, within split_error_bound_db of the reference.
    """
    train, weights, vario = _synthetic_map()
    rng = np.random.default_rng(7)
    n = 30_000
    flat = np.column_stack([rng.uniform(-600, 600, n), rng.uniform(-500, 450, n), np.full(n, 30.0)])
    assert krige_split(flat, train, weights, vario) is not None  # the fast path is taken
    dense = krige_dense(flat, train, weights, vario)
    assert np.abs(krige(flat, train, weights, vario) - dense).max() < kriging.SPLIT_TOLERANCE_DB
    # varying heights, exactly on samples, and far away (beyond SPLIT_FAR_RANGES * L)
    m = 2 * n  # a 3-D grid needs more queries to pay off (P >= 4 x grid nodes)
    mixed = np.vstack(
        [np.column_stack([rng.uniform(-200, 200, m), rng.uniform(-200, 200, m),
                          rng.uniform(25.0, 45.0, m)]),
         train[np.abs(train[:, :2]).max(1) < 200], [[5000.0, 5000.0, 30.0], [-400, 2500, 60]]]
    )  # fmt: skip
    fast = krige_split(mixed, train, weights, vario)
    assert fast is not None
    error = np.abs(fast - krige_dense(mixed, train, weights, vario))
    assert error[:-2].max() < kriging.SPLIT_TOLERANCE_DB
    assert error[-2:].max() <= split_error_bound_db(weights, vario) < 1e-4
    # small query sets take the dense path unchanged
    few = flat[:10]
    assert np.allclose(krige(few, train, weights, vario), dense[:10], rtol=0, atol=1e-12)


def test_a_degenerate_fit_is_flagged(tmp_path: Path) -> None:
    """A residual without spatial structure (the sample DT flight's LW2) fits sigma 0.001 dB
    and range 1 m: the map is its trend alone there, and fit-radiomap says so, one line."""
    flight = ROOT / "examples" / "samples" / "dt_flight.csv"
    done = run_cli("fit-radiomap", flight, "--out", tmp_path / "map.json", check=True)
    warnings = [w for w in done.stderr.strip().splitlines() if "degenerate" in w]
    assert len(warnings) == 1 and warnings[0].startswith("skymule: warning: LW2: degenerate fit")
    assert "sigma 0.001 dB, range 1.0 m" in warnings[0]
    shown = json.loads(
        run_cli("fit-radiomap", flight, "--out", tmp_path / "m.json", "--json").stdout
    )
    assert [w.split(":")[0] for w in shown["warnings"] if "degenerate" in w] == ["LW2"]
    sound = {"sensor": "A", "sigma_db": 4.0, "range_m": 30.0}
    assert fit_warnings([sound]) == ()
    assert len(fit_warnings([{**sound, "range_m": 1.0}])) == 1  # shortest range tried
    assert len(fit_warnings([{**sound, "sigma_db": 0.001}])) == 1  # no sill
    flat = {**sound, "sigma_db": 0.0, "range_m": 1.0}
    assert fit_warnings([flat], "log-distance") == ()  # it kriges nothing: nothing to flag
    assert "learned model alone" in fit_warnings([flat], "neural")[0]
