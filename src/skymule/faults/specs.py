"""Fault parameters: one validated model per ``[[faults]]`` kind (see ``docs/faults.md``).

A scenario lists faults as ``kind`` + ``params``::

    [[faults]]
    kind = "gilbert-elliott"
    params = { p_good_to_bad = 0.01, p_bad_to_good = 0.1, sensors = ["LW2"] }

:func:`fault_params` checks ``params`` against the kind's model (strict numbers, unknown keys
refused) and raises a one-line :class:`ValueError` naming the parameter, the value and what is
allowed; :mod:`skymule.scenario` reports it against the ``faults[i]`` entry. Units are SI
(seconds, metres, dB, m/s, watt-hours for the battery's capacity, as printed on packs).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

Probability = Annotated[float, Field(ge=0, le=1)]
Seconds = Annotated[float, Field(ge=0, le=1e7)]
PositiveSeconds = Annotated[float, Field(gt=0, le=1e7)]
Metres = Annotated[float, Field(ge=-1e4, le=1e4)]


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


class _SensorParams(_Params):
    sensors: Annotated[list[str], Field(min_length=1)] | None = None
    """Sensor names the fault applies to (default: every sensor)."""


class OutageParams(_SensorParams):
    """Tower outage windows: the listed sensors deliver nothing while a window is open.

    Fixed: ``start_s`` and ``duration_s`` give one window shared by the listed sensors.
    Random: omit ``start_s`` (start uniform over the mission) and/or give ``mean_duration_s``
    instead of ``duration_s`` (exponential length); each sensor draws ``windows`` windows of
    its own. Slot t is out when its start time t*slot_s lies in [start, start + length).
    """

    start_s: Seconds | None = None
    duration_s: PositiveSeconds | None = None
    mean_duration_s: PositiveSeconds | None = None
    windows: Annotated[int, Field(ge=1, le=1000)] = 1

    @model_validator(mode="after")
    def _one_length(self) -> OutageParams:
        if (self.duration_s is None) == (self.mean_duration_s is None):
            raise ValueError("give exactly one of duration_s (fixed) or mean_duration_s (random)")
        if self.start_s is not None and self.windows != 1:
            raise ValueError("windows > 1 needs a random start (leave start_s out)")
        return self


class GilbertElliottParams(_SensorParams):
    """Bursty link loss: a two-state (good/bad) Markov chain per sensor, one step a slot.

    Gilbert (1960), Elliott (1963). Long-run share of bad slots pi_B = p / (p + r); mean bad
    burst 1/r slots. A slot is lost with probability ``loss_good`` in the good state and
    ``loss_bad`` in the bad one (defaults 0 and 1: no data in the bad state).
    """

    p_good_to_bad: Probability
    """p: probability per slot of going from good to bad."""
    p_bad_to_good: Probability
    """r: probability per slot of going from bad to good."""
    loss_good: Probability = 0.0
    loss_bad: Probability = 1.0

    @model_validator(mode="after")
    def _moves(self) -> GilbertElliottParams:
        if self.p_good_to_bad + self.p_bad_to_good == 0:
            raise ValueError("p_good_to_bad and p_bad_to_good cannot both be 0")
        return self


class SnrErrorParams(_SensorParams):
    """Measurement error on the SNR the policy sees: bias + Gaussian noise [dB].

    With ``correlation_s`` > 0 the noise is a first-order autoregressive process with
    correlation exp(-slot_s / correlation_s) between consecutive slots (same variance).
    """

    bias_db: Annotated[float, Field(ge=-100, le=100)] = 0.0
    std_db: Annotated[float, Field(ge=0, le=100)] = 0.0
    correlation_s: Seconds = 0.0


class MissedPollParams(_Params):
    """Missed polls: slots in which nothing is served (no SNR report, no download).

    i.i.d. with ``probability``, or bursty: a two-state chain with ``p_good_to_bad`` and
    ``p_bad_to_good`` (every poll in the bad state is missed). Give one form.
    """

    probability: Probability | None = None
    p_good_to_bad: Probability | None = None
    p_bad_to_good: Probability | None = None

    @model_validator(mode="after")
    def _one_form(self) -> MissedPollParams:
        bursty = self.p_good_to_bad is not None or self.p_bad_to_good is not None
        if bursty == (self.probability is not None):
            raise ValueError(
                "give probability (i.i.d.) or p_good_to_bad and p_bad_to_good (bursty)"
            )
        if bursty and (self.p_good_to_bad is None or self.p_bad_to_good is None):
            raise ValueError("bursty missed polls need both p_good_to_bad and p_bad_to_good")
        if bursty and self.p_good_to_bad == 0 and self.p_bad_to_good == 0:
            raise ValueError("p_good_to_bad and p_bad_to_good cannot both be 0")
        return self


class GpsErrorParams(_Params):
    """Error on the position the UAV reports [m]: bias (east, north) + Gaussian noise."""

    bias_m: Annotated[list[Metres], Field(min_length=2, max_length=2)] = [0.0, 0.0]
    """Constant offset (east, north) [m]."""
    std_m: Annotated[float, Field(ge=0, le=1e4)] = 0.0
    """Standard deviation per axis [m]."""
    correlation_s: Seconds = 0.0
    """As for snr-error: AR(1) correlation time [s] (0: independent each slot)."""


class WindParams(_Params):
    """Steady wind [m/s] blowing from ``from_deg`` (degrees clockwise from north, as METAR)."""

    speed_mps: Annotated[float, Field(ge=0, le=100)]
    from_deg: Annotated[float, Field(ge=0, lt=360)] = 0.0


class BatteryParams(_Params):
    """Battery that forces the return home (propulsion energy, Zeng, Xu & Zhang 2019).

    The engine allows a move only if the energy used, the move's and the way home from where
    it ends (at ``return_speed_mps``, each leg at the ground speed a wind allows) fit the
    energy above the reserve; otherwise the UAV flies home and lands (``docs/faults.md``,
    step 6).
    """

    capacity_wh: Annotated[float, Field(gt=0, le=1e6)]
    reserve_fraction: Annotated[float, Field(ge=0, lt=1)] = 0.2
    return_speed_mps: Annotated[float, Field(gt=0, le=100)] = 10.0


FAULT_KINDS: dict[str, type[BaseModel]] = {
    "outage": OutageParams,
    "gilbert-elliott": GilbertElliottParams,
    "snr-error": SnrErrorParams,
    "missed-polls": MissedPollParams,
    "gps-error": GpsErrorParams,
    "wind": WindParams,
    "battery": BatteryParams,
}
"""``kind`` -> its parameter model."""

FaultParams = (
    OutageParams
    | GilbertElliottParams
    | SnrErrorParams
    | MissedPollParams
    | GpsErrorParams
    | WindParams
    | BatteryParams
)

SINGLE_KINDS = ("wind", "battery")
"""Kinds a scenario may list at most once (they describe the one UAV)."""


def _where(loc: tuple[int | str, ...]) -> str:
    text = "params"
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else f".{part}"
    return text


def fault_params(kind: str, params: dict[str, Any]) -> FaultParams:
    """The validated parameters of a fault; ``ValueError`` (one line) when they are wrong."""
    model = FAULT_KINDS.get(kind)
    if model is None:
        raise ValueError(f"kind = {kind!r} is not a fault; allowed: {', '.join(FAULT_KINDS)}")
    try:
        return model.model_validate(params)  # type: ignore[return-value]
    except ValidationError as exc:
        first = exc.errors()[0]
        where = _where(tuple(first["loc"]))
        message = first["msg"].removeprefix("Value error, ")
        if first["type"] == "extra_forbidden":
            allowed = ", ".join(model.model_fields)
            raise ValueError(f"{kind}: unknown parameter {where!r}; allowed: {allowed}") from None
        if first["type"] == "missing":
            raise ValueError(f"{kind}: {where} is required") from None
        if first["type"] in ("float_type", "int_type"):
            message = "must be a number (not a string, not true/false)"
        value = first.get("input")
        shown = "" if isinstance(value, dict) or where == "params" else f" = {value!r}"
        raise ValueError(f"{kind}: {where}{shown}: {message}") from None
