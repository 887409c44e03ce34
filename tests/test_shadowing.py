"""Shadowing (spatially consistent Gudmundson field) and small-scale fading."""

from __future__ import annotations

import numpy as np
import pytest

from skymule.policies import make_policy
from skymule.radio.fading import rician_power_db
from skymule.radio.shadowing import shadowing_field
from skymule.scenario import Scenario, load_scenario
from skymule.sim.run import run_mission
from skymule.world import build_mission

SIGMA_DB = 6.0
D_CORR_M = 50.0
REGION = np.array([[-1000.0, -1000.0], [1000.0, 1000.0]])


def _field(seed: int = 0, n_sensors: int = 4):
    return shadowing_field(np.random.default_rng(seed), n_sensors, SIGMA_DB, D_CORR_M, REGION)


def test_field_has_the_requested_std_and_gudmundson_correlation_at_d_corr() -> None:
    field = _field()
    rng = np.random.default_rng(7)
    a = rng.uniform(-900, 900, (200_000, 2))
    angle = rng.uniform(0, 2 * np.pi, 200_000)
    b = a + D_CORR_M * np.column_stack([np.cos(angle), np.sin(angle)])
    sa, sb = field.at(a), field.at(b)
    # std within 10 % (bilinear interpolation lowers it by <= 2.6 % between nodes)
    assert sa.std() == pytest.approx(SIGMA_DB, rel=0.10)
    # rho(d_corr) = exp(-1) = 0.368 (Gudmundson), off-grid pairs in random directions
    corr = np.mean([np.corrcoef(sa[:, i], sb[:, i])[0, 1] for i in range(sa.shape[1])])
    assert corr == pytest.approx(np.exp(-1.0), abs=0.07)
    # far apart (10 d_corr) the shadowing is uncorrelated
    c = a + 10 * D_CORR_M * np.column_stack([np.cos(angle), np.sin(angle)])
    far = np.mean([np.corrcoef(sa[:, i], field.at(c)[:, i])[0, 1] for i in range(4)])
    assert abs(far) < 0.07


def test_sensors_get_independent_fields() -> None:
    values = _field().at(np.random.default_rng(3).uniform(-900, 900, (50_000, 2)))
    corr = np.corrcoef(values.T)
    assert np.abs(corr[np.triu_indices(4, 1)]).max() < 0.1


def test_same_place_same_shadowing_and_seeded() -> None:
    field = _field(seed=5)
    points = np.array([[12.3, -45.6], [300.0, 200.0], [12.3, -45.6]])
    first = field.at(points)
    assert np.array_equal(first[0], first[2])  # visited twice in one query
    assert np.array_equal(field.at(points[::-1])[::-1], first)  # order of queries irrelevant
    assert np.array_equal(_field(seed=5).at(points), first)  # same seed, same field
    assert not np.allclose(_field(seed=6).at(points), first)  # other seed, other field
    # continuous: 0.1 m away changes it by far less than sigma
    assert np.abs(field.at(points + 0.1) - first).max() < 0.5


def _scenario(**radio: object) -> Scenario:
    base = load_scenario("paper-sim-fixed")
    waypoints = [[0, 0, 30], [-300, 0, 30], [0, 0, 30]]  # out and back: revisits every point
    return base.model_copy(
        update={
            "radio": base.radio.model_copy(update=radio),
            "trajectory": base.trajectory.model_copy(update={"waypoints": waypoints}),
            "mission": base.mission.model_copy(update={"duration_s": 60}),
        }
    )


def test_fixed_path_revisiting_a_point_sees_the_same_shadowing() -> None:
    mission = build_mission(_scenario(shadowing_std_db=SIGMA_DB))
    free = build_mission(_scenario())
    assert mission.track is not None and free.track is not None
    shadow = mission.track.snr_db - free.track.snr_db
    assert np.abs(shadow).max() > 1.0  # shadowing is on
    # sample k (outbound) and sample 60 - k (return) are the same place
    assert np.allclose(mission.track.position_m[10], mission.track.position_m[50])
    assert np.allclose(shadow[10], shadow[50], atol=1e-9)
    # the autonomous engine queries the same source: same place, same value
    assert mission.source is not None
    again = mission.source.snr_db(mission.track.position_m[[10, 50]])
    assert np.allclose(again, mission.track.snr_db[[10, 50]])


def test_rician_moments_match_the_k_factor() -> None:
    # unit mean power; E|h|^4 = (K^2 + 4K + 2) / (K + 1)^2 = 142 / 121 = 1.1736 for K = 10 dB
    power = 10 ** (rician_power_db(np.random.default_rng(0), (400_000,), 10.0) / 10)
    assert power.mean() == pytest.approx(1.0, abs=0.01)
    assert np.mean(power**2) == pytest.approx(142 / 121, abs=0.01)
    # Rayleigh (K = 0): |h|^2 exponential with mean 1, P(|h|^2 < 1) = 1 - 1/e = 0.632
    rayleigh = 10 ** (rician_power_db(np.random.default_rng(1), (400_000,), -np.inf) / 10)
    assert np.mean(rayleigh < 1.0) == pytest.approx(1 - np.exp(-1), abs=0.005)


def test_fading_varies_while_hovering_and_policies_share_the_draws() -> None:
    mission = build_mission(_scenario(fading="rician", rician_k_db=3.0))
    assert mission.fading_db is not None and mission.fading_db.shape == (60, 4)
    assert mission.track is not None
    logs = {
        name: run_mission(
            mission, make_policy(mission.scenario.policy.model_copy(update={"name": name}))
        )
        for name in ("greedy", "hgad")
    }
    for log in logs.values():
        # what the UAV observed = the track's SNR at its sample + this slot's fading
        sample = np.argmin(
            np.linalg.norm(log.position_m[:, None, :] - mission.track.position_m[None], axis=-1),
            axis=1,
        )
        expected = mission.track.snr_db[sample] + mission.fading_db[: log.n_slots]
        assert np.allclose(log.snr_db, expected)
        assert np.allclose(log.rate_bps, mission.rate_bps(expected))
    hgad = logs["hgad"]
    hover = np.flatnonzero(hgad.hovering[:-1] & hgad.hovering[1:])
    assert hover.size > 0, "HGAD should hover on this path"
    t = int(hover[0])
    assert np.allclose(hgad.position_m[t], hgad.position_m[t + 1])
    assert not np.allclose(hgad.snr_db[t], hgad.snr_db[t + 1])  # same place, new fade
    # same seed, same draws; fading never changes the track's own SNR
    again = build_mission(_scenario(fading="rician", rician_k_db=3.0))
    assert np.array_equal(again.fading_db, mission.fading_db)
    assert np.array_equal(again.track.snr_db, build_mission(_scenario()).track.snr_db)
