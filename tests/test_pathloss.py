"""Path-loss models against values worked out by hand from their published formulas."""

from __future__ import annotations

import numpy as np
import pytest

from skymule.errors import SkymuleError
from skymule.radio.pathloss import (
    AL_HOURANI_ENVIRONMENTS,
    PATHLOSS_MODELS,
    Aerial3GPP,
    AlHourani,
    FreeSpace,
    LogDistance,
    TwoRay,
)
from skymule.radio.sources import build_pathloss
from skymule.scenario import RadioSpec

F_HZ = 3.41e9  # AADM carrier; wavelength c / f = 0.087916 m
ORIGIN = np.array([[0.0, 0.0, 0.0]])


def test_free_space_at_100_m() -> None:
    # 20 log10(4 pi 100 m / 0.087916 m) = 20 log10(14293.5) = 83.103 dB
    loss = FreeSpace(F_HZ).loss_db(np.array([[100.0, 0.0, 0.0]]), ORIGIN)
    assert loss.shape == (1, 1)
    assert loss[0, 0] == pytest.approx(83.103, abs=1e-3)


def test_log_distance_with_given_reference() -> None:
    # PL(1000 m) = 60 + 10 * 3 * log10(1000 / 10) = 60 + 60 = 120 dB
    model = LogDistance(F_HZ, exponent=3.0, reference_distance_m=10.0, reference_loss_db=60.0)
    loss = model.loss_db(np.array([[1000.0, 0.0, 0.0], [10.0, 0.0, 0.0]]), ORIGIN)
    assert loss[:, 0] == pytest.approx([120.0, 60.0])


def test_two_ray_exact_phasor_sum() -> None:
    # h_t = 10 m, h_r = 30 m, d = 200 m: d_los = 200.9975 m, d_ref = 203.9608 m;
    # -20 log10(lambda/(4 pi) |e^{-jk d_los}/d_los - e^{-jk d_ref}/d_ref|) = 85.167 dB
    loss = TwoRay(F_HZ).loss_db(np.array([[200.0, 0.0, 30.0]]), np.array([[0.0, 0.0, 10.0]]))
    assert loss[0, 0] == pytest.approx(85.167, abs=1e-3)


def test_two_ray_tends_to_fourth_power_law_far_away() -> None:
    # beyond the crossover distance: PL ~ 40 log10 d - 20 log10(h_t h_r) = 200 - 49.54 dB
    loss = TwoRay(F_HZ).loss_db(np.array([[1e5, 0.0, 30.0]]), np.array([[0.0, 0.0, 10.0]]))
    assert loss[0, 0] == pytest.approx(150.458, abs=0.1)


def test_al_hourani_suburban_high_elevation_is_nearly_free_space_plus_eta_los() -> None:
    # theta = 45 deg: P_LoS = 1/(1 + 4.88 exp(-0.43 (45 - 4.88))) = 0.99999984;
    # PL = FSPL(141.42 m) + 0.1 P + 21 (1 - P) = 86.1131 + 0.1 = 86.2132 dB
    model = AlHourani(F_HZ, AL_HOURANI_ENVIRONMENTS["suburban"])
    loss = model.loss_db(np.array([[100.0, 0.0, 100.0]]), ORIGIN)
    assert loss[0, 0] == pytest.approx(86.2132, abs=1e-3)


def test_al_hourani_urban_at_30_degrees() -> None:
    # theta = 30 deg, d = 200 m: P_LoS = 1/(1 + 9.61 exp(-0.16 (30 - 9.61))) = 0.73098;
    # PL = FSPL(200 m) + 1.0 * 0.73098 + 20 * 0.26902 = 89.1235 + 6.1114 = 95.2349 dB
    model = AlHourani(F_HZ, AL_HOURANI_ENVIRONMENTS["urban"])
    uav = np.array([[100.0 * np.sqrt(3.0), 0.0, 100.0]])
    assert model.los_probability(uav, ORIGIN)[0, 0] == pytest.approx(0.73098, abs=1e-5)
    assert model.loss_db(uav, ORIGIN)[0, 0] == pytest.approx(95.2349, abs=1e-3)


def test_3gpp_rma_av_at_30_m_and_1_km() -> None:
    # h = 30 m: d1 = 1350.8 log10 30 - 1602 = 393.30 m, p1 = 15021 log10 30 - 16053 = 6134.8 m
    # P_LoS(1000 m) = 0.3933 + exp(-1000/6134.8) (1 - 0.3933) = 0.90874
    # PL_LoS = (23.9 - 1.8 log10 30) log10(1000.45) + 20 log10(40 pi 3.41/3) = 106.825 dB
    # PL_NLoS = max(PL_LoS, -12 + (35 - 5.3 log10 30) log10(1000.45) + ...) = 112.616 dB
    # expected loss = 0.90874 * 106.825 + 0.09126 * 112.616 = 107.353 dB
    model = Aerial3GPP(F_HZ, "rma")
    uav = np.array([[1000.0, 0.0, 30.0]])
    assert model.los_probability(uav, ORIGIN)[0, 0] == pytest.approx(0.90874, abs=1e-5)
    assert model.loss_db(uav, ORIGIN)[0, 0] == pytest.approx(107.353, abs=1e-3)


def test_3gpp_uma_av_at_50_m_and_1_km() -> None:
    # h = 50 m: d1 = 460 log10 50 - 700 = 81.53 m, p1 = 4300 log10 50 - 3800 = 3505.6 m
    # P_LoS(1000 m) = 0.08153 + exp(-1000/3505.6) (1 - 0.08153) = 0.77205
    # PL_LoS = 28 + 22 log10(1001.25) + 20 log10 3.41 = 104.667 dB
    # PL_NLoS = -17.5 + (46 - 7 log10 50) log10(1001.25) + 20 log10(40 pi 3.41/3) = 127.937 dB
    # expected loss = 109.971 dB
    model = Aerial3GPP(F_HZ, "uma")
    uav = np.array([[1000.0, 0.0, 50.0]])
    assert model.los_probability(uav, ORIGIN)[0, 0] == pytest.approx(0.77205, abs=1e-5)
    assert model.loss_db(uav, ORIGIN)[0, 0] == pytest.approx(109.971, abs=1e-3)


def test_3gpp_los_is_certain_above_its_height_and_close_in() -> None:
    rma, uma = Aerial3GPP(F_HZ, "rma"), Aerial3GPP(F_HZ, "uma")
    assert rma.los_probability(np.array([[3000.0, 0.0, 41.0]]), ORIGIN)[0, 0] == 1.0
    assert uma.los_probability(np.array([[3000.0, 0.0, 101.0]]), ORIGIN)[0, 0] == 1.0
    assert uma.los_probability(np.array([[10.0, 0.0, 30.0]]), ORIGIN)[0, 0] == 1.0


@pytest.mark.parametrize(("scenario", "height"), [("uma", 20.0), ("rma", 5.0), ("rma", 400.0)])
def test_3gpp_height_outside_range_names_the_model(scenario: str, height: float) -> None:
    with pytest.raises(SkymuleError, match=rf"3gpp-{scenario}-av.*{height:.1f} m is outside"):
        Aerial3GPP(F_HZ, scenario).loss_db(np.array([[100.0, 0.0, height]]), ORIGIN)


@pytest.mark.parametrize("name", PATHLOSS_MODELS.names())
def test_every_registered_model_is_vectorised_and_grows_with_distance(name: str) -> None:
    model = build_pathloss(RadioSpec(model=name))
    sensors = np.array([[0.0, 0.0, 10.0], [500.0, 0.0, 5.0], [0.0, 300.0, 0.0]])
    uav = np.column_stack([np.linspace(-900, 900, 7), np.full(7, 200.0), np.full(7, 60.0)])
    loss = model.loss_db(uav, sensors)
    assert loss.shape == (7, 3)
    assert np.isfinite(loss).all()
    # one row at a time gives the same values (no cross-talk between positions)
    assert np.allclose(np.vstack([model.loss_db(u[None], sensors) for u in uav]), loss)
    if name != "two-ray":  # two-ray oscillates before its crossover distance
        near = model.loss_db(np.array([[0.0, 50.0, 60.0]]), sensors[:1])
        far = model.loss_db(np.array([[0.0, 2000.0, 60.0]]), sensors[:1])
        assert far[0, 0] > near[0, 0] + 20.0
