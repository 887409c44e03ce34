"""Learned twins (``fit-radiomap --method neural``) and ``skymule sim2real``, on small flights
(the learned twin's own tests: tests/test_learned_twin.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import lawnmower, run_cli
from skymule.geo import LocalFrame
from skymule.io.traces import read_trace, write_aadm_log, write_dt_export
from skymule.radio.radiomap import read_radiomap

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "examples" / "samples"
ORIGIN = (35.7274824, -78.6962749)
TOWER = np.array([60.0, -40.0, 10.0])


def test_cli_methods_and_learned_twin_on_the_samples(tmp_path: Path) -> None:
    """Every method from the one command; the learned twin's map is a signal source."""
    flight = read_trace(SAMPLES / "flight_merged.csv")
    keep = slice(0, 150)  # the first 150 s: enough for every method, quick to fit
    assert flight.lat_deg is not None and flight.lon_deg is not None
    real = write_aadm_log(
        tmp_path / "flight.csv", flight.time_s[keep], flight.snr_db[keep], flight.columns,
        flight.lat_deg[keep], flight.lon_deg[keep], flight.z_m[keep],
    )  # fmt: skip
    for method in ("log-distance", "gp"):
        out = tmp_path / f"{method}.json"
        done = run_cli("fit-radiomap", real, "--method", method, "--out", out, "--json",
                       check=True)  # fmt: skip
        rows = json.loads(done.stdout)["sensors"]
        assert [r["sensor"] for r in rows] == ["LW1", "LW2", "LW3", "LW4"]
        assert all(r["cv_rmse_map_db"] < r["cv_rmse_baseline_db"] + 1.0 for r in rows)
        assert read_radiomap(out).method == method
    learned = tmp_path / "learned.json"
    run_cli(
        "fit-radiomap", real, "--method", "neural", "--prior", SAMPLES / "dt_flight.csv",
        "--out", learned, check=True,
    )  # fmt: skip
    fitted = read_radiomap(learned)
    assert fitted.method == "neural" and fitted.prior is not None
    scores = json.loads(run_cli("score-radiomap", learned, real, "--json", check=True).stdout)
    dt_scores = json.loads(
        run_cli("score-radiomap", "paper-sim-fixed", real, "--json", check=True).stdout
    )
    # in sample, the learned twin fits the flight it saw better than the model does
    assert np.mean(list(scores["rmse_db"].values())) < np.mean(list(dt_scores["rmse_db"].values()))


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--method", "nueral"], "--method 'nueral': allowed: kriging, log-distance, gp, neural"),
        (["--prior", "paper-sim-fixed"], "--prior calibrates a learned map"),
        (["--method", "neural", "--prior", "nowhere-preset"], "nowhere-preset"),
    ],
)
def test_fit_mistakes_are_one_line(tmp_path: Path, args: list[str], needle: str) -> None:
    done = run_cli("fit-radiomap", SAMPLES / "dt_flight.csv", "--out", tmp_path / "m.json", *args)
    assert done.returncode == 2, done.stderr
    assert needle in done.stderr and len(done.stderr.strip().splitlines()) == 1


SCENARIO = """
name = "twin-test"
[mission]
duration_s = 10
[site]
origin = { lat = 35.7274824, lon = -78.6962749 }
[[sensors]]
name = "LW1"
x_m = 60.0
y_m = -40.0
height_m = 10.0
buffer_mbit = 40
[[sensors]]
name = "LW2"
x_m = -200.0
y_m = 150.0
height_m = 10.0
buffer_mbit = 60
[radio]
model = "fspl"
[trajectory]
waypoints = [[0, 0, 30], [10, 0, 30]]
"""


def _real_flight(tmp_path: Path, scenario: Path, noise_db: float) -> Path:
    """A merged log whose SNR is the scenario's free space (+ noise) at its positions."""
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    mission = build_mission(load_scenario(scenario))
    assert mission.source is not None
    positions = lawnmower(120)
    snr = mission.source.snr_db(positions)
    snr += noise_db * np.random.default_rng(4).standard_normal(snr.shape)
    lat, lon = LocalFrame(*ORIGIN).to_latlon(positions[:, 0], positions[:, 1])
    path = tmp_path / f"real-{noise_db:g}.csv"
    write_aadm_log(path, np.arange(120.0), snr.round(2), ["LW1", "LW2"], lat.round(9),
                   lon.round(9), positions[:, 2])  # fmt: skip
    return path


def test_sim2real_of_the_true_model_is_exact_and_json_has_the_issues_shape(
    tmp_path: Path,
) -> None:
    scenario = tmp_path / "twin.toml"
    scenario.write_text(SCENARIO)
    real = _real_flight(tmp_path, scenario, 0.0)
    noisy = _real_flight(tmp_path, scenario, 6.0)
    dt = tmp_path / "dt.csv"
    positions = lawnmower(120)
    write_dt_export(dt, np.arange(120.0), np.full((120, 2), 45.0), ["LW1", "LW2"],
                    positions[:, 0], positions[:, 1], positions[:, 2])  # fmt: skip
    done = run_cli(
        "sim2real", scenario, real, "--twin", scenario, "--twin", dt,
        "--policies", "greedy,hgad", "--json", check=True,
    )  # fmt: skip
    document = json.loads(done.stdout)
    exact, flat = document["twins"]
    assert exact["twin"] == str(scenario) and flat["twin"] == str(dt)
    for twin in (exact, flat):
        assert set(twin["rmse_db"]) == set(twin["bias_db"]) == {"LW1", "LW2"}
        for policy in ("greedy", "hgad"):
            entry = twin["policies"][policy]
            assert {"real_mbit", "twin_mbit", "error"} <= set(entry)  # today's fields kept
            assert entry["error"] == pytest.approx(
                (entry["twin_mbit"] - entry["real_mbit"]) / entry["real_mbit"]
            )
            assert {"same_decisions_error", "regret", "own_error"} <= set(entry)
    # the model that made the flight predicts it (to the log's 0.01-dB rounding)
    assert max(exact["rmse_db"].values()) < 0.01
    assert all(abs(v["error"]) < 1e-3 for v in exact["policies"].values())
    for entry in exact["policies"].values():  # trusting the true model costs nothing
        assert entry["regret"] == 0.0 and entry["regret_ci"] == [0.0, 0.0]
        assert abs(entry["same_decisions_error"]) < 1e-3
    assert document["ranking"][0]["twin"] == str(scenario)
    assert document["trust"].startswith(f"trust {scenario}: its decisions cost 0.0%")
    # a flat 45-dB twin is optimistic where the towers are far, and predicts more Mbit
    assert min(flat["bias_db"].values()) > 5.0
    assert flat["policies"]["greedy"]["twin_mbit"] >= flat["policies"]["greedy"]["real_mbit"]
    out = tmp_path / "s2r"
    run_cli(
        "sim2real", scenario, noisy, "--twin", scenario, "--policies", "greedy",
        "--out", out, "--no-pdf", check=True,
    )  # fmt: skip
    written = json.loads((out / "sim2real.json").read_text())
    assert written["twins"][0]["rmse_db"]["LW1"] == pytest.approx(6.0, rel=0.2)
    html = (out / "report.html").read_text()
    for figure in ("sim2real-snr-time", "sim2real-scatter", "sim2real-rmse", "sim2real-ranking"):
        assert f'data-fig="{figure}"' in html
        assert (out / "figures" / f"{figure}.png").stat().st_size > 5_000
    (out / "report.html").unlink()
    run_cli("report", out, "--no-pdf", check=True)  # rebuilt from the folder's files alone
    assert "Sim-to-real" in (out / "report.html").read_text()
    refused = run_cli("sim2real", scenario, noisy, "--twin", scenario, "--out", SAMPLES)
    assert refused.returncode == 2 and "--out" in refused.stderr


def test_sim2real_mistakes_are_one_line(tmp_path: Path) -> None:
    scenario = tmp_path / "twin.toml"
    scenario.write_text(SCENARIO)
    real = _real_flight(tmp_path, scenario, 0.0)
    cases = [
        (["--twin", "examples/paper-rw-flight1.toml"], "replays a flight and predicts nothing"),
        (["--twin", "missing.json"], "missing.json"),
        (["--twin", str(scenario), "--policies", "gredy"], "gredy"),
    ]
    for args, needle in cases:
        done = run_cli("sim2real", scenario, real, *args, cwd=ROOT)
        assert done.returncode == 2, (args, done.stderr)
        assert needle in done.stderr and len(done.stderr.strip().splitlines()) == 1


BIG_BUFFERS = SCENARIO.replace("buffer_mbit = 40", "buffer_mbit = 100000").replace(
    "buffer_mbit = 60", "buffer_mbit = 100000"
)


def test_a_biased_twin_with_the_same_decisions_costs_nothing_but_misses_the_mbit(
    tmp_path: Path,
) -> None:
    """6 dB optimistic everywhere: Greedy (argmax SNR) decides as on the real flight, so its
    regret is 0, while the same decisions download more on the twin; the real side of the
    same decisions is the engine's own download (the replay is the slot contract)."""
    from skymule.tasks.sim2real import sim2real

    scenario = tmp_path / "big.toml"
    scenario.write_text(BIG_BUFFERS)
    biased = tmp_path / "biased.toml"
    biased.write_text(BIG_BUFFERS.replace('model = "fspl"', 'model = "fspl"\ntx_power_dbm = 16.0'))
    real = _real_flight(tmp_path, scenario, 0.0)
    result = sim2real(str(scenario), real, [str(biased)], ["greedy", "hgad"])
    (twin,) = result.twins
    greedy = twin.numbers["greedy"]
    assert greedy.regret.value == 0.0
    assert greedy.same_decisions_error.value > 0.03  # measured 0.074: the table saturates
    assert greedy.same_decisions_error.low > 0.0  # the interval excludes 0 too
    assert greedy.own_error is not None and greedy.own_error.value > 0.03
    for numbers in twin.numbers.values():
        assert numbers.same_real_mbit == pytest.approx(numbers.real_mbit, rel=1e-9)
        assert numbers.decisions == "policy on the real trace"
    hgad = twin.numbers["hgad"]
    if hgad.hover_slots_real or hgad.hover_slots_twin:
        assert hgad.own_error is None and "hovers" in (hgad.own_error_note or "")
    assert twin.policies["greedy"]["regret"] == 0.0  # the plain-dict view reads the same
    assert twin.scores["bias_db"]["LW1"] == twin.metrics.towers["LW1"]["bias_db"].value
    # the twin's bias shows in the table, not in the references
    assert twin.metrics.towers["LW1"]["bias_db"].value == pytest.approx(6.0, abs=0.02)
    labels = [r.reference for r in result.references]
    assert labels == ["noise floor", "free space", "oracle log-distance"]
    assert any("--calibration" in note for note in result.notes)
    oracle = result.references[-1].scores.towers["LW1"]
    assert oracle["rmse_db"].value < 0.5  # free space is a log-distance trend


def test_sim2real_on_the_samples_prints_references_policy_numbers_and_the_twin_to_trust(
    tmp_path: Path,
) -> None:
    """Several twins on the shipped flight, with its download log and a calibration set."""
    args: list[str | Path] = [
        "sim2real", "paper-sim-fixed", SAMPLES / "flight_merged.csv",
        "--twin", SAMPLES / "dt_flight.csv", "--twin", SAMPLES / "flight2_merged.csv",
        "--twin", "paper-sim-fixed", "--policies", "greedy,hgad",
        "--download-log", SAMPLES / "flight_downloads_tower.csv",
        "--calibration", SAMPLES / "dt_flight.csv", "--block", "12",
    ]  # fmt: skip
    done = run_cli(*args, "--out", tmp_path / "s2r", "--no-pdf", check=True)
    text = done.stdout
    for row in ("ref: noise floor", "ref: free space", "ref: log-distance",
                "ref: oracle log-distance", "best link", "undefined: hovers"):  # fmt: skip
        assert row in text, row
    assert "block bootstrap, 12 samples a block" in text
    trust = [line for line in text.splitlines() if line.startswith("trust ")]
    assert len(trust) == 1
    document = json.loads((tmp_path / "s2r" / "sim2real.json").read_text())
    assert document["bootstrap"]["block"] == 12
    assert set(document) >= {"real_mbit", "twins", "references", "ranking", "trust", "notes"}
    assert trust[0] == document["trust"]
    ranking = document["ranking"]
    assert len(ranking) == 3 and ranking[0]["twin"] in document["trust"]
    regrets = [r["regret"] for r in ranking]
    assert regrets == sorted(regrets)
    for twin in document["twins"]:
        assert set(twin["ci"]["rmse_db"]) == {"LW1", "LW2", "LW3", "LW4"}
        for tower, (low, high) in twin["ci"]["rmse_db"].items():
            assert low <= twin["rmse_db"][tower] <= high
        assert set(twin["best_link"]) >= {"rate_rmse_mbps", "rate_bias_mbps", "ci"}
        for policy, entry in twin["policies"].items():
            assert entry["decisions"] == "recorded"  # the flight's own, from its log
            for key in ("same_decisions_error", "regret"):
                low, high = entry[f"{key}_ci"]
                assert low <= entry[key] <= high
            if policy == "greedy":  # never hovers: its own error is defined
                assert entry["own_error"] is not None and entry["own_error_note"] is None
            else:  # HGAD hovers on the trace: no percentage, the samples reached instead
                assert entry["own_error"] is None and entry["hover_slots_real"] > 0
                assert 0 <= entry["last_sample_real"] < entry["n_samples"] == 360
    # the same decisions of every policy are the recorded ones: one number per twin
    for twin in document["twins"]:
        values = {e["same_decisions_error"] for e in twin["policies"].values()}
        assert len(values) == 1
    references = {r["reference"]: r for r in document["references"]}
    assert references["log-distance"]["fitted_on"] == "dt_flight.csv"
    # the two-ray twin misses this flight by more than free space does, and is told so
    worse = [n for n in document["notes"] if n.startswith("dt_flight.csv: mean SNR RMSE")]
    assert len(worse) == 1 and "worse than free space" in worse[0] and worse[0] in text
    floor = references["noise floor"]["rmse_db"]
    oracle = references["oracle log-distance"]["rmse_db"]
    assert all(floor[t] < oracle[t] for t in floor)  # no trend beats the trace's own noise
    html = (tmp_path / "s2r" / "report.html").read_text()
    assert document["trust"].split(":")[0] in html
    bad = run_cli(*args[:3], "--twin", "paper-sim-fixed", "--calibration", tmp_path / "no.csv")
    assert bad.returncode == 2 and "--calibration" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1
