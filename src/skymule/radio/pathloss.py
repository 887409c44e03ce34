"""Path-loss models: distance (and geometry) -> loss in dB, vectorised.

Every model is a frozen dataclass with one method, ``loss_db(uav_m, sensor_m)``, taking UAV
positions of shape (P, 3) and sensor antenna positions of shape (N, 3) in local metres and
returning losses of shape (P, N) in dB. Models resolve by name through :data:`PATHLOSS_MODELS`,
where each declares its own parameter model (the ``[radio.params]`` table of a scenario) and
whether it is ``monotone`` (loss non-decreasing in horizontal distance at a fixed UAV altitude,
which the autonomous bound relies on).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Literal, Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from skymule.errors import SkymuleError
from skymule.registry import Registry

SPEED_OF_LIGHT_MPS = 299_792_458.0
"""Speed of light in vacuum [m/s]."""

MIN_DISTANCE_M = 1.0
"""Distances are clipped below this [m] so that the far-field formulas stay finite."""


def distance_3d_m(uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
    """3-D distances [m], shape (P, N), from UAV positions (P, 3) to sensors (N, 3)."""
    uav = np.asarray(uav_m, float)[:, None, :]
    sensors = np.asarray(sensor_m, float)[None, :, :]
    dx, dy, dz = (uav[..., k] - sensors[..., k] for k in range(3))
    # summed in np.sum's order over three values, without a reduction over a length-3 axis
    return np.sqrt((dx * dx + dy * dy) + dz * dz)


def fspl_db(distance_m: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Free-space path loss [dB]: FSPL(d) = 20 log10(4 pi d f / c) (Friis)."""
    d = np.maximum(np.asarray(distance_m, float), MIN_DISTANCE_M)
    return 20.0 * np.log10(4.0 * np.pi * d * frequency_hz / SPEED_OF_LIGHT_MPS)


class PathLossModel(Protocol):
    """Anything that maps UAV positions (P, 3) and sensors (N, 3) to losses (P, N) in dB."""

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class FreeSpace:
    """Free-space (Friis) path loss over the 3-D UAV-sensor distance."""

    frequency_hz: float

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        return fspl_db(distance_3d_m(uav_m, sensor_m), self.frequency_hz)


@dataclass(frozen=True)
class LogDistance:
    """Log-distance path loss: PL(d) = PL(d0) + 10 n log10(d / d0).

    ``reference_loss_db`` is PL(d0); when None it is the free-space loss at ``d0``
    (Rappaport, *Wireless Communications*, 2nd ed., eq. 4.68).
    """

    frequency_hz: float
    exponent: float = 2.0
    reference_distance_m: float = 1.0
    reference_loss_db: float | None = None

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        d0 = self.reference_distance_m
        pl0 = (
            float(fspl_db(np.asarray(d0), self.frequency_hz))
            if self.reference_loss_db is None
            else self.reference_loss_db
        )
        d = np.maximum(distance_3d_m(uav_m, sensor_m), MIN_DISTANCE_M)
        return pl0 + 10.0 * self.exponent * np.log10(d / d0)


def horizontal_distance_m(uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
    """Horizontal (2-D) distances [m], shape (P, N), from UAV positions (P, 3) to sensors (N, 3)."""
    uav = np.asarray(uav_m, float)[:, None, :2]
    sensors = np.asarray(sensor_m, float)[None, :, :2]
    return np.sqrt(np.sum((uav - sensors) ** 2, axis=-1))


MIN_HEIGHT_M = 1.0
"""Two-ray: antenna heights above the ground plane are clipped below this [m]."""


@dataclass(frozen=True)
class TwoRay:
    """Two-ray ground-reflection model, exact phasor sum of the direct and reflected rays.

    With wavelength lambda, heights h_t (sensor) and h_r (UAV) above a flat ground plane
    z = 0, horizontal distance d, direct path d_los = sqrt(d^2 + (h_r - h_t)^2) and
    reflected path d_ref = sqrt(d^2 + (h_r + h_t)^2)::

        PL = -20 log10( lambda / (4 pi) * | exp(-j k d_los) / d_los
                                           + Gamma exp(-j k d_ref) / d_ref | ),  k = 2 pi / lambda

    (Rappaport, *Wireless Communications*, 2nd ed., Sec. 4.6, eqs. 4.36-4.47; Goldsmith,
    *Wireless Communications*, 2005, eq. 2.12 with unit antenna gains). ``reflection`` is the
    ground reflection coefficient Gamma (-1: perfect reflector at grazing incidence). Far beyond
    the crossover distance this tends to 40 log10 d - 20 log10(h_t h_r) (Rappaport eq. 4.52).
    Heights below :data:`MIN_HEIGHT_M` are clipped to it (at h = 0 the rays cancel exactly).
    """

    frequency_hz: float
    reflection: float = -1.0

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        uav = np.asarray(uav_m, float)
        sensors = np.asarray(sensor_m, float)
        d = horizontal_distance_m(uav, sensors)
        h_r = np.maximum(uav[:, 2], MIN_HEIGHT_M)[:, None]
        h_t = np.maximum(sensors[:, 2], MIN_HEIGHT_M)[None, :]
        d_los = np.maximum(np.sqrt(d**2 + (h_r - h_t) ** 2), MIN_DISTANCE_M)
        d_ref = np.sqrt(d**2 + (h_r + h_t) ** 2)
        wavelength = SPEED_OF_LIGHT_MPS / self.frequency_hz
        k = 2.0 * np.pi / wavelength
        field = np.exp(-1j * k * d_los) / d_los + self.reflection * np.exp(-1j * k * d_ref) / d_ref
        gain = wavelength / (4.0 * np.pi) * np.abs(field)
        return -20.0 * np.log10(np.maximum(gain, 1e-30))


def elevation_deg(uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
    """Elevation angle [deg] of the UAV seen from each sensor, shape (P, N), in [-90, 90]."""
    uav = np.asarray(uav_m, float)
    sensors = np.asarray(sensor_m, float)
    dz = uav[:, None, 2] - sensors[None, :, 2]
    return np.degrees(np.arctan2(dz, horizontal_distance_m(uav, sensors)))


@dataclass(frozen=True)
class AlHouraniParams:
    """Environment parameters of the Al-Hourani air-to-ground model.

    a, b: S-curve parameters of the LoS probability; eta_los_db, eta_nlos_db: mean excess
    losses over free space of LoS and NLoS links [dB].
    """

    a: float
    b: float
    eta_los_db: float
    eta_nlos_db: float


AL_HOURANI_ENVIRONMENTS: dict[str, AlHouraniParams] = {
    "suburban": AlHouraniParams(4.88, 0.43, 0.1, 21.0),
    "urban": AlHouraniParams(9.61, 0.16, 1.0, 20.0),
    "dense-urban": AlHouraniParams(12.08, 0.11, 1.6, 23.0),
    "high-rise-urban": AlHouraniParams(27.23, 0.08, 2.3, 34.0),
}
"""Al-Hourani, Kandeepan, Lardner, "Optimal LAP altitude for maximum coverage", IEEE Wireless
Commun. Lett. 3(6), 2014, Table I (ITU-R P.1410 built-up statistics, 2 GHz)."""


@dataclass(frozen=True)
class AlHourani:
    """Air-to-ground mean path loss (Al-Hourani et al., IEEE WCL 2014, eqs. 3-5).

    With elevation angle theta [deg] of the UAV seen from the sensor::

        P_LoS(theta) = 1 / (1 + a exp(-b (theta - a)))                      (eq. 3 form)
        PL = FSPL(d) + eta_LoS P_LoS + eta_NLoS (1 - P_LoS)                (eq. 5)

    i.e. the expected loss over the LoS/NLoS state; the random part is left to shadowing.
    Negative elevations (UAV below the antenna) count as 0 degrees.
    """

    frequency_hz: float
    environment: AlHouraniParams

    def los_probability(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        """(P, N) probability of line of sight."""
        theta = np.maximum(elevation_deg(uav_m, sensor_m), 0.0)
        env = self.environment
        return 1.0 / (1.0 + env.a * np.exp(-env.b * (theta - env.a)))

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        p_los = self.los_probability(uav_m, sensor_m)
        env = self.environment
        excess = env.eta_los_db * p_los + env.eta_nlos_db * (1.0 - p_los)
        return fspl_db(distance_3d_m(uav_m, sensor_m), self.frequency_hz) + excess


def _los_probability_3gpp(d2d_m: np.ndarray, d1_m: np.ndarray, p1_m: np.ndarray) -> np.ndarray:
    """TR 36.777 Table B-1 form: 1 if d2D <= d1, else d1/d2D + exp(-d2D/p1) (1 - d1/d2D)."""
    d = np.maximum(d2d_m, 1e-9)
    ratio = np.minimum(d1_m / d, 1.0)
    return np.where(d2d_m <= d1_m, 1.0, ratio + np.exp(-d / p1_m) * (1.0 - ratio))


@dataclass(frozen=True)
class Aerial3GPP:
    """3GPP TR 36.777 (Rel-15, "Enhanced LTE support for aerial vehicles") Annex B aerial-UE
    channel: LoS probability (Table B-1) and LoS/NLoS path loss (Table B-2) for the rural
    (``rma``) and urban (``uma``) macro scenarios, fc in GHz, distances in m, h = UAV height::

        RMa-AV, 10 m < h <= 300 m
          P_LoS: h <= 40 m: d1 = max(1350.8 log10 h - 1602, 18), p1 = max(15021 log10 h - 16053,
                 1000); h > 40 m: 1
          PL_LoS  = max(23.9 - 1.8 log10 h, 20) log10 d3D + 20 log10(40 pi fc / 3)
          PL_NLoS = max(PL_LoS, -12 + (35 - 5.3 log10 h) log10 d3D + 20 log10(40 pi fc / 3))
        UMa-AV, 22.5 m < h <= 300 m
          P_LoS: h <= 100 m: d1 = max(460 log10 h - 700, 18), p1 = 4300 log10 h - 3800;
                 h > 100 m: 1
          PL_LoS  = 28 + 22 log10 d3D + 20 log10 fc
          PL_NLoS = -17.5 + (46 - 7 log10 h) log10 d3D + 20 log10(40 pi fc / 3)

    with P_LoS = 1 for d2D <= d1, else d1/d2D + exp(-d2D/p1)(1 - d1/d2D). The returned loss is
    the expected loss P_LoS PL_LoS + (1 - P_LoS) PL_NLoS (the LoS state's randomness is left to
    shadowing). Heights outside the model's range raise :class:`SkymuleError` (the terrestrial
    TR 38.901 branches below 10 m / 22.5 m are not implemented).
    """

    frequency_hz: float
    scenario: str  # "rma" or "uma"

    @property
    def height_range_m(self) -> tuple[float, float]:
        return (10.0, 300.0) if self.scenario == "rma" else (22.5, 300.0)

    def _check_height(self, h_m: np.ndarray) -> None:
        low, high = self.height_range_m
        bad = (h_m < low) | (h_m > high)
        if np.any(bad):
            value = float(h_m[np.argmax(bad)])
            raise SkymuleError(
                f"radio.model = '3gpp-{self.scenario}-av': UAV height {value:.1f} m is outside "
                f"the {low:g}..{high:g} m the 3GPP TR 36.777 model covers; fly within it "
                "(trajectory waypoints z / altitude_m) or choose another radio.model"
            )

    def los_probability(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        """(P, N) probability of line of sight (TR 36.777 Table B-1)."""
        h = np.asarray(uav_m, float)[:, 2]
        self._check_height(h)
        log_h = np.log10(h)[:, None]
        d2d = horizontal_distance_m(uav_m, sensor_m)
        if self.scenario == "rma":
            d1 = np.maximum(1350.8 * log_h - 1602.0, 18.0)
            p1 = np.maximum(15021.0 * log_h - 16053.0, 1000.0)
            always = h[:, None] > 40.0
        else:
            d1 = np.maximum(460.0 * log_h - 700.0, 18.0)
            p1 = np.maximum(4300.0 * log_h - 3800.0, 1e-9)
            always = h[:, None] > 100.0
        return np.where(always, 1.0, _los_probability_3gpp(d2d, d1, p1))

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        p_los = self.los_probability(uav_m, sensor_m)
        fc_ghz = self.frequency_hz / 1e9
        log_h = np.log10(np.asarray(uav_m, float)[:, 2])[:, None]
        log_d = np.log10(np.maximum(distance_3d_m(uav_m, sensor_m), MIN_DISTANCE_M))
        free = 20.0 * np.log10(40.0 * np.pi * fc_ghz / 3.0)
        if self.scenario == "rma":
            pl_los = np.maximum(23.9 - 1.8 * log_h, 20.0) * log_d + free
            pl_nlos = np.maximum(pl_los, -12.0 + (35.0 - 5.3 * log_h) * log_d + free)
        else:
            pl_los = 28.0 + 22.0 * log_d + 20.0 * np.log10(fc_ghz)
            pl_nlos = -17.5 + (46.0 - 7.0 * log_h) * log_d + free
        return p_los * pl_los + (1.0 - p_los) * pl_nlos


# ---------------------------------------------------------------------------
# Registry: [radio] model name -> builder, parameter model, monotone flag
# ---------------------------------------------------------------------------


class ModelParams(BaseModel):
    """Base of every path-loss model's ``[radio.params]`` model (no parameters)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


class LogDistanceParams(ModelParams):
    path_loss_exponent: Annotated[float, Field(gt=0)] = 2.0
    """Path-loss exponent n."""
    reference_distance_m: Annotated[float, Field(gt=0)] = 1.0
    """Reference distance d0 [m]."""
    reference_loss_db: float | None = None
    """Loss at d0 [dB]; default free space at d0."""


class TwoRayParams(ModelParams):
    ground_reflection: Annotated[float, Field(ge=-1, le=1)] = -1.0
    """Ground reflection coefficient Gamma (-1: perfect reflector, grazing)."""


class AlHouraniModelParams(ModelParams):
    environment: Literal["suburban", "urban", "dense-urban", "high-rise-urban"] = "suburban"
    """Built-up environment (Al-Hourani et al. 2014, Table I)."""


@dataclass(frozen=True)
class PathLossKind:
    """A registered path-loss model: how to build it from (frequency, params)."""

    build: Callable[[float, ModelParams], PathLossModel]
    params: type[ModelParams]
    monotone: bool
    """True when the loss never decreases with horizontal distance at a fixed UAV altitude
    (no shadowing); the autonomous bound then uses exact reach sets."""


def _log_distance(frequency_hz: float, params: ModelParams) -> PathLossModel:
    assert isinstance(params, LogDistanceParams)
    return LogDistance(
        frequency_hz,
        exponent=params.path_loss_exponent,
        reference_distance_m=params.reference_distance_m,
        reference_loss_db=params.reference_loss_db,
    )


def _two_ray(frequency_hz: float, params: ModelParams) -> PathLossModel:
    assert isinstance(params, TwoRayParams)
    return TwoRay(frequency_hz, reflection=params.ground_reflection)


def _al_hourani(frequency_hz: float, params: ModelParams) -> PathLossModel:
    assert isinstance(params, AlHouraniModelParams)
    return AlHourani(frequency_hz, AL_HOURANI_ENVIRONMENTS[params.environment])


PATHLOSS_MODELS: Registry[PathLossKind] = Registry("radio.model")
"""``[radio] model`` name -> :class:`PathLossKind`."""

PATHLOSS_MODELS.register("fspl", PathLossKind(lambda f, p: FreeSpace(f), ModelParams, True))
PATHLOSS_MODELS.register("free-space", PathLossKind(lambda f, p: FreeSpace(f), ModelParams, True))
PATHLOSS_MODELS.register("log-distance", PathLossKind(_log_distance, LogDistanceParams, True))
PATHLOSS_MODELS.register("two-ray", PathLossKind(_two_ray, TwoRayParams, False))
# monotone for every tabulated environment (eta_NLoS >= eta_LoS); the bound re-checks it
PATHLOSS_MODELS.register("al-hourani", PathLossKind(_al_hourani, AlHouraniModelParams, True))
PATHLOSS_MODELS.register(
    "3gpp-rma-av", PathLossKind(lambda f, p: Aerial3GPP(f, "rma"), ModelParams, True)
)
PATHLOSS_MODELS.register(
    "3gpp-uma-av", PathLossKind(lambda f, p: Aerial3GPP(f, "uma"), ModelParams, False)
)
