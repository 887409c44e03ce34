"""Scenario files: a validated, serialisable description of one mission.

A scenario is TOML (schema: docs/cli.md). It is validated by pydantic models that
forbid unknown keys, so a misspelt field is an error, never silently ignored. Mbit and lat/lon
appear here, at the edge; :mod:`skymule.world` turns a scenario into SI arrays.

Built-in presets live in ``skymule/scenarios/*.toml`` and resolve by name wherever a scenario
path is accepted.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Sequence
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    model_validator,
)
from pydantic_core import ErrorDetails, PydanticCustomError

from skymule.aadm.rules import TESTBED_POLL_INTERVAL_S
from skymule.errors import ScenarioError, SkymuleError
from skymule.faults.specs import SINGLE_KINDS, fault_params
from skymule.io.textfiles import parse_toml, read_text
from skymule.limits import (
    ALTITUDE_LIMIT,
    COORDINATE_LIMIT,
    MAX_ALTITUDE_M,
    MAX_BANDWIDTH_HZ,
    MAX_BUFFER_MBIT,
    MAX_COORDINATE_M,
    MAX_DURATION_S,
    MAX_SPEED_MPS,
    SPEED_LIMIT,
    waypoint_problem,
)
from skymule.overrides import apply_override
from skymule.policies.registry import (
    POLICIES,
    NoParams,
    check_policy_name,
    is_model_file,
    is_plugin,
    policy_params_model,
)
from skymule.radio.pathloss import PATHLOSS_MODELS
from skymule.registry import Registry, did_you_mean, unknown_name_message

PositiveFloat = Annotated[float, Field(gt=0)]


def _at_most(limit: float, words: str) -> AfterValidator:
    def check(value: float) -> float:
        if value > limit:
            raise ValueError(words)
        return value

    return AfterValidator(check)


Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE_M, le=MAX_COORDINATE_M)]
Speed = Annotated[float, Field(gt=0), _at_most(MAX_SPEED_MPS, SPEED_LIMIT)]
"""A UAV speed [m/s], within :data:`skymule.limits.MAX_SPEED_MPS`."""
Altitude = Annotated[float, Field(gt=0), _at_most(MAX_ALTITUDE_M, ALTITUDE_LIMIT)]
"""A flight altitude above take-off [m], within :data:`skymule.limits.MAX_ALTITUDE_M`."""
Distance = Annotated[float, Field(gt=0), _at_most(MAX_COORDINATE_M, COORDINATE_LIMIT)]


def _check_point(value: LatLon | list[float] | None) -> LatLon | list[float] | None:
    """A home point: lat/lon (bounded by its model) or ``[x_m, y_m]`` within the local frame."""
    if isinstance(value, list):
        if len(value) != 2:
            raise ValueError("give [x_m, y_m] (two numbers) or a {lat, lon} table")
        for number in value:
            if not math.isfinite(number) or abs(number) > MAX_COORDINATE_M:
                raise ValueError(f"{number!r}: {COORDINATE_LIMIT}")
    return value


def _check_waypoints(value: list[list[float]] | str | None) -> list[list[float]] | str | None:
    if isinstance(value, list):
        if any(len(point) != 3 for point in value):
            raise ValueError("every waypoint must be [x_m, y_m, z_m]")
        problem = waypoint_problem(np.asarray(value, float))
        if problem is not None:
            raise ValueError(problem)
    return value


class _Spec(BaseModel):
    # strict: a number must be a TOML/JSON number (no "200" strings, no true/false as 1/0);
    # an integer is still accepted where a float is expected
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


class LatLon(_Spec):
    lat: Annotated[float, Field(ge=-90, le=90)]
    lon: Annotated[float, Field(ge=-180, le=180)]


class MissionSpec(_Spec):
    duration_s: Annotated[float, Field(gt=0, le=MAX_DURATION_S)] | None = None
    """Mission time T*slot_s [s]; omitted for a trace source means the trace's length."""
    slot_s: PositiveFloat = 1.0
    """Slot length [s]."""
    aadm_window_s: PositiveFloat | None = None
    """Close the download window this long after the start [s], as the AADM controller does
    at 500 s: later slots serve nothing. None: downloads count until the mission ends."""


class AadmSpec(_Spec):
    """How the AADM testbed runs a mission (``skymule.aadm.score.predicted_testbed_score``)."""

    poll_interval_s: Annotated[float, Field(ge=1.0, le=10.0)] = TESTBED_POLL_INTERVAL_S
    """Mean wall time between the UAV's polls on the testbed [s] (1.031: 330 polls in 339.2 s
    of the recorded flight log; its controller answers at most one poll a second)."""
    poll_jitter_s: Annotated[float, Field(ge=0.0, le=5.0)] = 0.0
    """Standard deviation of that time [s], drawn from the scenario's seed (0: steady)."""


class SiteSpec(_Spec):
    origin: LatLon = LatLon(lat=35.7274824, lon=-78.6962749)
    """Origin of the local east/north frame (default: the AADM launch point)."""
    geofence: str | None = None
    """Built-in site name (``lake-wheeler``) or a KML/GeoJSON path; optional."""


class SensorSpec(_Spec):
    name: Annotated[str, Field(min_length=1)]
    lat: Annotated[float, Field(ge=-90, le=90)] | None = None
    lon: Annotated[float, Field(ge=-180, le=180)] | None = None
    x_m: Coordinate | None = None
    y_m: Coordinate | None = None
    height_m: Coordinate = 10.0
    """Antenna height [m] relative to the take-off ground."""
    buffer_mbit: Annotated[float, Field(ge=0, le=MAX_BUFFER_MBIT)]

    @model_validator(mode="after")
    def _one_position(self) -> SensorSpec:
        has_latlon = self.lat is not None or self.lon is not None
        has_xy = self.x_m is not None or self.y_m is not None
        if has_latlon and has_xy:
            raise ValueError("give either lat/lon or x_m/y_m, not both")
        if has_latlon and (self.lat is None or self.lon is None):
            raise ValueError("give both lat and lon")
        if has_xy and (self.x_m is None or self.y_m is None):
            raise ValueError("give both x_m and y_m")
        return self

    @property
    def has_position(self) -> bool:
        return self.lat is not None or self.x_m is not None


class RadioSpec(_Spec):
    model: str = "fspl"
    """Path-loss model name (see ``skymule.radio.pathloss.PATHLOSS_MODELS``)."""
    params: dict[str, Any] = Field(default_factory=dict)
    """The path-loss model's own parameters (``[radio.params]``), validated by its model.

    The older flat keys (``path_loss_exponent``, ``environment``, ... directly in ``[radio]``)
    are still read and override the same key in ``params``; parameters of *other* path-loss
    models are kept and ignored, so ``compare --sources`` can switch models."""
    frequency_hz: PositiveFloat = 3.41e9
    tx_power_dbm: float = 10.0
    tx_gain_dbi: float = 10.0
    rx_gain_dbi: float = 2.0
    noise_dbm: float = -90.0
    bandwidth_hz: Annotated[float, Field(gt=0, le=MAX_BANDWIDTH_HZ)] = 1.4e6
    """Channel bandwidth [Hz], at most :data:`~skymule.limits.MAX_BANDWIDTH_HZ` (100 GHz)."""
    rate_table: str = "aadm-lte-cqi"
    shadowing_std_db: Annotated[float, Field(ge=0, le=30)] = 0.0
    """Log-normal shadowing standard deviation [dB] (0: none); model sources only."""
    shadowing_decorrelation_m: PositiveFloat = 50.0
    """Shadowing decorrelation distance d_corr [m] (Gudmundson: rho(d) = exp(-d / d_corr))."""
    fading: Literal["none", "rician", "rayleigh"] = "none"
    """Small-scale fading, drawn per slot and sensor."""
    rician_k_db: Annotated[float, Field(ge=-30, le=40)] = 10.0
    """rician: K factor [dB] (power of the specular part over the scattered part)."""

    @model_validator(mode="before")
    @classmethod
    def _flat_params(cls, data: Any) -> Any:
        return _lift_flat_params(data, _pathloss_param_names())

    @model_validator(mode="after")
    def _check_params(self) -> RadioSpec:
        if self.model not in PATHLOSS_MODELS:
            raise _component_error(
                unknown_name_message("radio.model", self.model, PATHLOSS_MODELS.names())
            )
        self.model_params()
        return self

    def model_params(self) -> BaseModel:
        """The path-loss model's validated parameters (defaults filled in)."""
        kind = PATHLOSS_MODELS.get(self.model)
        return validate_params(
            kind.params, self.params, _pathloss_param_names(), f"radio.model {self.model!r}"
        )

    def param(self, name: str) -> Any:
        """One parameter of the path-loss model (its default when not given)."""
        return _param(self.model_params(), name, f"radio.model {self.model!r}")


class SignalSpec(_Spec):
    source: Literal["model", "trace", "radiomap"] = "model"
    trace: str | None = None
    """Recorded flight (AADM merged log or digital-twin export)."""
    traces: list[str] | None = None
    """radiomap: recorded flights to fit the radio map to."""
    map: str | None = None
    """radiomap: a map fitted earlier (``skymule fit-radiomap ... --out map.json``)."""
    sensors_from_trace: list[str] | None = None
    """Trace SNR column for each scenario sensor, in sensor order (default: by name)."""

    @model_validator(mode="after")
    def _trace_given(self) -> SignalSpec:
        if self.source == "trace" and not self.trace:
            raise ValueError("source = 'trace' needs trace = 'FILE.csv'")
        if self.source == "radiomap" and bool(self.traces) == bool(self.map):
            raise ValueError(
                "source = 'radiomap' needs either traces = ['FLIGHT.csv', ...] or "
                "map = 'map.json' (exactly one of them)"
            )
        return self


class TrajectorySpec(_Spec):
    mode: Literal["fixed", "autonomous"] = "fixed"
    waypoints: Annotated[list[list[float]] | str | None, AfterValidator(_check_waypoints)] = None
    """Fixed path: [[x, y, z], ...] metres, or a CSV path (x_m,y_m,z_m or lat,lon,alt)."""
    flight: Annotated[str, Field(min_length=1)] | None = None
    """Fixed path: a recorded flight (any trace format: AADM merged log, digital-twin export)
    whose positions over time are flown, resampled to the slots by time; its SNR columns are
    ignored (the signal source gives the SNR). Instead of ``waypoints``."""
    speed_mps: Speed = 10.0
    """Nominal speed along a fixed path [m/s]."""
    home: Annotated[LatLon | list[float] | None, AfterValidator(_check_point)] = None
    """Autonomous: home point, lat/lon or [x, y] metres (default: the site origin)."""
    altitude_m: Altitude = 30.0
    """Autonomous: flight altitude [m]."""
    max_speed_mps: Speed = 10.0
    return_home: bool = True
    visit_radius_m: Distance = 50.0

    @model_validator(mode="after")
    def _one_path(self) -> TrajectorySpec:
        if self.flight is not None and self.waypoints is not None:
            raise ValueError("give either waypoints or flight (a recorded flight), not both")
        if self.flight is not None and self.mode != "fixed":
            raise ValueError(
                "flight flies a recorded path: it needs mode = 'fixed' (an autonomous UAV "
                "chooses its own path)"
            )
        return self


class PolicySpec(_Spec):
    name: str = "hgad"
    """A registered policy (``skymule.policies.POLICIES``) or ``"package.module:Class"``."""
    params: dict[str, Any] = Field(default_factory=dict)
    """The policy's own parameters (``[policy.params]``), validated by its parameter model.

    HGAD's ``hover_threshold`` and ``max_hover_s`` may also be written directly in
    ``[policy]`` (older files) and then override ``params``; parameters of *other*
    registered policies are kept and ignored, so one file can run under several policies.
    When a command runs other policies than the file's (``--policy``, ``--policies``, a sweep's
    ``policy.name`` axis), each gets the keys it declares (:func:`route_policy_params`)."""

    @model_validator(mode="before")
    @classmethod
    def _flat_params(cls, data: Any) -> Any:
        return _lift_flat_params(data, _policy_param_names())

    @model_validator(mode="after")
    def _check_params(self, info: ValidationInfo) -> PolicySpec:
        # a plug-in's module is not imported to check a file (it may never run: an override,
        # `bound`): its name is checked here, its parameters when it is made
        try:
            check_policy_name(self.name)
        except SkymuleError as exc:
            raise _component_error(str(exc)) from None
        if self.name in POLICIES:
            # the policies the command runs (validation context), else this one: a key may be
            # a plug-in's among them, which only running it can tell (route_policy_params)
            running = (info.context or {}).get(RUNNING, (self.name,))
            keys_known = not any(is_plugin(name) for name in running)
            self._validated(POLICIES.meta(self.name, "params", NoParams), keys_known)
        return self

    def _validated(self, model: type[BaseModel], keys_known: bool = True) -> BaseModel:
        shared = _policy_param_names()
        if not keys_known:  # only this policy's own values are checked here
            shared = shared.union(self.params)
        return validate_params(model, self.params, shared, f"policy {self.name!r}")

    def policy_params(self) -> BaseModel | None:
        """The policy's validated parameters, or None for a plug-in without a ``Params`` model.

        For a plug-in this imports its module (call it for a policy that runs); a problem is
        one :class:`SkymuleError` line.
        """
        from_policy = policy_params_model(self.name)
        if from_policy is None:
            return None
        try:
            return self._validated(from_policy)
        except PydanticCustomError as exc:
            raise SkymuleError(f"policy.{exc.message()}") from None

    def param(self, name: str) -> Any:
        """One parameter of the policy (its default when not given).

        The batched engine reads HGAD's ``hover_threshold``/``max_hover_s`` through this.
        """
        validated = self.policy_params()
        if validated is None:
            if name in self.params:
                return self.params[name]
            raise SkymuleError(f"policy {self.name!r} has no parameter {name!r}")
        return _param(validated, name, f"policy {self.name!r}")

    @property
    def hover_threshold(self) -> float:
        """HGAD's trigger fraction (kept for code that read the old flat field)."""
        return float(self.param("hover_threshold"))

    @property
    def max_hover_s(self) -> float:
        """HGAD's longest hover [s] (kept for code that read the old flat field)."""
        return float(self.param("max_hover_s"))


def _lift_flat_params(data: Any, names: frozenset[str]) -> Any:
    """Move the older flat parameter keys of a section into its ``params`` table."""
    if not isinstance(data, dict):
        return data
    flat = {k: v for k, v in data.items() if k in names}
    if not flat:
        return data
    params = data.get("params", {})
    if not isinstance(params, dict):
        return data  # the field validator reports it
    rest = {k: v for k, v in data.items() if k not in names}
    return {**rest, "params": {**params, **flat}}


def validate_params(
    model: type[BaseModel], params: dict[str, Any], shared: frozenset[str], owner: str
) -> BaseModel:
    """``params`` validated by a component's parameter ``model``.

    Keys that belong to other components of the same kind (``shared``) and not to this one
    are ignored; anything else wrong is a one-line ``PydanticCustomError`` naming the key.
    """
    fields = list(model.model_fields)
    own = {k: v for k, v in params.items() if k in fields or k not in shared}
    unknown = [k for k in own if k not in fields]  # also when the model allows extra keys
    if unknown:
        allowed = ", ".join(fields) or "none"
        hint = did_you_mean(unknown[0], fields)
        raise _component_error(
            f"params.{unknown[0]}: unknown parameter of {owner}; its parameters: {allowed}{hint}"
        )
    try:
        return model.model_validate(own)
    except ValidationError as exc:
        first = _first_error(exc)
        key = _location(tuple(first["loc"]))
        if first["type"] == "missing":
            text = f"params.{key} is required by {owner}"
        else:
            message = _STRICT_TYPE_HINTS.get(
                first["type"], first["msg"].removeprefix("Value error, ")
            )
            text = f"params.{key} = {first.get('input')!r}: {message}"
        raise _component_error(text) from None


def _component_error(text: str) -> PydanticCustomError:
    # the text goes in the context: a template would read braces in it as placeholders
    return PydanticCustomError("component_params", "{text}", {"text": text})


def _param(validated: BaseModel, name: str, owner: str) -> Any:
    if name not in type(validated).model_fields:
        raise SkymuleError(f"{owner} has no parameter {name!r}")
    return getattr(validated, name)


RUNNING = "running"
"""Validation-context key: the policy names a command runs (``load_scenario(policies=...)``)."""


def policy_param_names(name: str) -> frozenset[str] | None:
    """The parameters policy ``name`` declares (None: a plug-in without ``Params``, which takes
    the whole table). A plug-in's module is imported: call it for a policy that runs."""
    if is_model_file(name):
        return frozenset()
    try:
        model = policy_params_model(name)
    except SkymuleError as exc:
        raise ScenarioError(str(exc)) from None
    return None if model is None else frozenset(model.model_fields)


def policy_shares(
    keys: Iterable[str], names: Sequence[str], owner: str | None = None
) -> list[frozenset[str] | None]:
    """The ``[policy.params]`` keys each of ``names`` keeps (None: all of them), for the
    policies that run (a plug-in among them is imported).

    A policy keeps the keys it declares and those of the registered policies (kept and
    ignored, as ever); a plug-in without ``Params`` keeps the whole table. A key that none of
    ``names`` nor any registered policy declares is one line with a "did you mean", unless
    ``owner`` (the file's own policy) is a plug-in that does not run: its keys cannot be known
    without importing it, which the override makes pointless.
    """
    registered = _policy_param_names()
    declared = [policy_param_names(name) for name in names]
    fields: set[str] = set()
    for own in declared:
        fields.update(own or ())
    owner_unknown = owner is not None and is_plugin(owner) and owner not in names
    if not owner_unknown and all(own is not None for own in declared):
        unknown = [key for key in keys if key not in fields and key not in registered]
        if unknown:
            who = "policy" if len(names) == 1 else "policies"
            its = "its" if len(names) == 1 else "their"
            raise ScenarioError(
                f"policy.params.{unknown[0]}: unknown parameter of {who} "
                f"{', '.join(map(repr, names))}; {its} parameters: "
                f"{', '.join(sorted(fields)) or 'none'}{did_you_mean(unknown[0], sorted(fields))}"
            )
    return [None if own is None else own | registered for own in declared]


def route_policy_params(
    params: dict[str, Any], names: Sequence[str], owner: str | None = None
) -> list[dict[str, Any]]:
    """Each of ``names``' share of one ``[policy.params]`` table (:func:`policy_shares`)."""
    return [
        dict(params) if keep is None else {k: v for k, v in params.items() if k in keep}
        for keep in policy_shares(params, names, owner)
    ]


def plugin_default_overrides(params: dict[str, Any], names: Sequence[str], owner: str) -> list[str]:
    """One line for each ``[policy.params]`` key written for the scenario's own policy
    ``owner`` that replaces the default a *plug-in* among ``names`` declares for it (a
    preset's HGAD longest hover given to a plug-in whose own default is shorter): the value
    is applied, as :func:`route_policy_params` shares it out, and the user is told."""
    lines = []
    shares = route_policy_params(params, names, owner)
    for name, share in zip(names, shares, strict=True):
        if name == owner or not is_plugin(name):
            continue
        model = policy_params_model(name)
        fields = model.model_fields if model is not None else {}
        for key, value in share.items():
            field = fields.get(key)
            if field is None or field.is_required() or field.default == value:
                continue
            lines.append(
                f"policy.params.{key} = {value!r} (written for {owner!r}) replaces "
                f"{name!r}'s own default {field.default!r}"
            )
    return lines


def _pathloss_param_names() -> frozenset[str]:
    return _pathloss_names(len(PATHLOSS_MODELS))


def _policy_param_names() -> frozenset[str]:
    return _policy_names(len(POLICIES))


# Registries only grow (``register``; nothing is removed or replaced), so their size keys
# what was registered: a scenario's validation asks for these names a few times, and a sweep
# validates thousands of scenarios against the same registries.
@functools.lru_cache(maxsize=8)
def _pathloss_names(count: int) -> frozenset[str]:
    return _param_names_of_models(tuple(kind.params for _, kind in PATHLOSS_MODELS.items()))


@functools.lru_cache(maxsize=8)
def _policy_names(count: int) -> frozenset[str]:
    return _param_names_of_models(
        tuple(policy_params_model(policy) or BaseModel for policy in POLICIES.names())
    )


@functools.lru_cache(maxsize=8)
def _param_names_of_models(models: tuple[type[BaseModel], ...]) -> frozenset[str]:
    """Every field name of ``models`` (cached by the registered models: a sweep validates
    thousands of missions against the same registry; a newly registered one is a new key)."""
    return frozenset(name for model in models for name in model.model_fields)


class FaultSpec(_Spec):
    """One ``[[faults]]`` entry: a fault ``kind`` and its ``params`` (see docs/faults.md)."""

    kind: str
    params: dict[str, Any] = {}

    @model_validator(mode="after")
    def _valid_params(self) -> FaultSpec:
        fault_params(self.kind, self.params)  # one-line ValueError naming the parameter
        return self


class UavSpec(_Spec):
    """One UAV of a fleet (``[[uavs]]``); unset fields come from ``[trajectory]``/``[policy]``."""

    name: Annotated[str, Field(min_length=1)]
    home: Annotated[LatLon | list[float] | None, AfterValidator(_check_point)] = None
    """Home point, lat/lon or [x, y] metres (default: ``trajectory.home``)."""
    altitude_m: Altitude | None = None
    """Autonomous flight altitude [m] (default: ``trajectory.altitude_m``)."""
    max_speed_mps: Speed | None = None
    """Speed cap (autonomous) or speed along the path (fixed) [m/s]."""
    waypoints: Annotated[list[list[float]] | str | None, AfterValidator(_check_waypoints)] = None
    """Fixed path of this UAV (as ``trajectory.waypoints``)."""
    policy: PolicySpec | None = None
    """This UAV's own policy (default: the scenario's ``[policy]``)."""


class Scenario(_Spec):
    """A validated mission description: the TOML file, field for field (``extra="forbid"``).

    Sections: ``[mission]`` (duration, slot length, download window), ``[site]`` (origin,
    geofence), ``[[sensors]]`` (positions, buffers), ``[radio]`` (path loss, link budget, rate
    table, shadowing, fading), ``[signal]`` (model, radio map or recorded trace),
    ``[trajectory]`` (fixed waypoints or autonomous flight: home, speed, altitude, return
    home), ``[policy]`` (name and ``[policy.params]``), ``[[faults]]`` and ``[[uavs]]``
    (several UAVs), ``[aadm]`` (the AADM testbed's poll cadence). Load one with
    :func:`load_scenario`; ``to_toml_dict`` writes it back.
    """

    name: str = "scenario"
    seed: Annotated[int, Field(ge=0, lt=2**63)] = 0
    """Seeds every random draw of the mission (shadowing, fading)."""
    mission: MissionSpec = MissionSpec()
    site: SiteSpec = SiteSpec()
    sensors: Annotated[list[SensorSpec], Field(min_length=1)]
    radio: RadioSpec = RadioSpec()
    signal: SignalSpec = SignalSpec()
    trajectory: TrajectorySpec = TrajectorySpec()
    policy: PolicySpec = PolicySpec()
    faults: list[FaultSpec] | None = None
    """Faults injected into the mission (none by default); see docs/faults.md."""
    uavs: list[UavSpec] | None = None
    """Several UAVs sharing the sensors' buffers (``docs/fleet.md``); None: one UAV."""
    aadm: AadmSpec | None = None
    """The AADM testbed's poll cadence (docs/aadm.md); None: its recorded 1.031 s a poll."""
    base_dir: str = Field(default=".", exclude=True)
    """Folder that relative paths in the scenario are resolved against (not serialised)."""

    @model_validator(mode="after")
    def _unique_names(self) -> Scenario:
        names = [s.name for s in self.sensors]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"sensor names must be unique; repeated: {', '.join(duplicates)}")
        uavs = [u.name for u in self.uavs or []]
        repeated = sorted({n for n in uavs if uavs.count(n) > 1})
        if repeated:
            raise ValueError(f"uavs: names must be unique; repeated: {', '.join(repeated)}")
        if self.uavs is not None and not self.uavs:
            raise ValueError("uavs = []: give at least one [[uavs]] table, or leave it out")
        return self

    @model_validator(mode="after")
    def _faults_fit(self) -> Scenario:
        names = [s.name for s in self.sensors]
        for index, fault in enumerate(self.faults or ()):
            unknown = [n for n in fault.params.get("sensors") or () if n not in names]
            if unknown:
                raise ValueError(
                    f"faults[{index}] ({fault.kind}): sensor {unknown[0]!r} is not in the "
                    f"scenario; allowed: {', '.join(names)}"
                )
            if fault.kind == "battery" and self.trajectory.mode == "fixed":
                raise ValueError(
                    f"faults[{index}] (battery): a battery limit needs trajectory.mode = "
                    "'autonomous' (a fixed path cannot turn home when the energy runs low)"
                )
            if fault.kind == "wind" and not self.uavs:  # a fleet checks each UAV (sim.fleet)
                uav = (
                    self.trajectory.max_speed_mps
                    if self.trajectory.mode == "autonomous"
                    else self.trajectory.speed_mps
                )
                if fault.params["speed_mps"] >= uav:
                    raise ValueError(
                        f"faults[{index}] (wind): speed_mps = {fault.params['speed_mps']!r} "
                        f"must be below the UAV's speed ({uav} m/s) or it cannot hold position"
                    )
        kinds = [f.kind for f in self.faults or ()]
        repeated = sorted({k for k in SINGLE_KINDS if kinds.count(k) > 1})
        if repeated:
            raise ValueError(f"faults: at most one {repeated[0]!r} entry (there is one UAV)")
        return self

    def resolve_path(self, value: str) -> Path:
        """``value`` as a path: absolute as given, else relative to the scenario's folder."""
        path = Path(value)
        return path if path.is_absolute() else Path(self.base_dir) / path

    def with_policy(self, name: str) -> Scenario:
        """This scenario under policy ``name`` (its parameters carried over where they fit)."""
        return self.with_policies([name])[0]

    def with_policies(self, names: Sequence[str]) -> list[Scenario]:
        """This scenario under each of ``names``, which are about to run (a plug-in among them
        is imported): ``[policy.params]`` is shared out by :func:`route_policy_params`."""
        shares = route_policy_params(self.policy.params, names, self.policy.name)
        scenarios = []
        for name, params in zip(names, shares, strict=True):
            try:
                policy = PolicySpec.model_validate({"name": name, "params": params})
            except ValidationError as exc:
                message = _first_error(exc)["msg"]
                where = "policy." if message.startswith("params.") else ""
                raise ScenarioError(f"{where}{message}") from None
            scenarios.append(self.model_copy(update={"policy": policy}))
        return scenarios

    def to_toml_dict(self) -> dict[str, Any]:
        """The scenario as plain TOML/JSON values (unset fields left out), as a file holds it."""
        return self.model_dump(mode="json", exclude_none=True)


def _location(loc: tuple[int | str, ...]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif not str(part).startswith("function-") and part not in ("list[float]", "str"):
            text += f".{part}" if text else str(part)
    return text


def _first_error(error: ValidationError) -> ErrorDetails:
    """The error to report: a misspelt key first (it often causes the "required" one)."""
    errors = error.errors()
    for kind in ("component_params", "extra_forbidden"):
        for item in errors:
            if item["type"] == kind:
                return item
    return errors[0]


def _fields_at(loc: tuple[int | str, ...]) -> list[str]:
    """Field names of the scenario section at ``loc`` (for "did you mean")."""
    model: Any = Scenario
    for part in loc:
        if isinstance(part, int):
            continue
        field = model.model_fields.get(str(part)) if hasattr(model, "model_fields") else None
        if field is None:
            return []
        annotation = field.annotation
        for arg in (*getattr(annotation, "__args__", ()), annotation):
            if isinstance(arg, type) and issubclass(arg, BaseModel):
                model = arg
                break
        else:
            return []
    return list(model.model_fields) if hasattr(model, "model_fields") else []


_STRICT_TYPE_HINTS = {
    "float_type": "must be a number (not a string, not true/false)",
    "int_type": "must be a whole number (not a string, a fraction or true/false)",
    "string_type": "must be a string (in quotes)",
    "bool_type": "must be true or false",
}
"""One-line messages for the strict type checks (pydantic's own name Python types, not TOML's)."""


def format_validation_error(source: str, error: ValidationError) -> str:
    """The first validation problem as one line: ``source: field = value: what is allowed``."""
    first = _first_error(error)
    loc = tuple(first["loc"])
    where = _location(loc)
    message = first["msg"].removeprefix("Value error, ")
    if first["type"] == "component_params":
        prefix = f"{where}." if where and message.startswith("params.") else ""
        return f"{source}: {prefix}{message}"
    if first["type"] == "extra_forbidden":
        fields = [f for f in _fields_at(loc[:-1]) if f != "base_dir"]
        hint = did_you_mean(str(loc[-1]), fields)
        return (
            f"{source}: unknown field {where!r}{hint or '; check its spelling against the schema'}"
        )
    if first["type"] == "missing":
        return f"{source}: {where} is required"
    if first["type"] in _STRICT_TYPE_HINTS:
        message = _STRICT_TYPE_HINTS[first["type"]]
    value = first.get("input")
    shown = "" if isinstance(value, dict) else f" = {value!r}"
    return f"{source}: {where or 'scenario'}{shown}: {message}"


def scenario_from_dict(
    data: dict[str, Any], source: str, base_dir: Path, *, policies: Sequence[str] | None = None
) -> Scenario:
    """The validated scenario of a TOML/JSON table; ``policies``: the ones the caller will run
    instead of the file's own (their parameters may sit in ``[policy.params]``)."""
    context = None if policies is None else {RUNNING: tuple(policies)}
    try:
        return Scenario.model_validate({**data, "base_dir": str(base_dir)}, context=context)
    except ValidationError as exc:
        raise ScenarioError(format_validation_error(source, exc)) from None


def presets() -> Registry[str]:
    """The built-in scenario presets: name -> TOML text (with its comments)."""
    folder = resources.files("skymule").joinpath("scenarios")
    registry: Registry[str] = Registry("scenario", extra_allowed="or a scenario TOML path")
    for item in sorted(folder.iterdir(), key=lambda p: p.name):
        if item.name.endswith(".toml"):
            registry.register(item.name[:-5], item.read_text())
    return registry


def preset_names() -> list[str]:
    """Names of the built-in scenario presets."""
    return presets().names()


def load_scenario(
    spec: str | Path, overrides: Sequence[str] = (), *, policies: Sequence[str] | None = None
) -> Scenario:
    """Load a scenario from a TOML path or a built-in preset name.

    ``overrides`` are ``key=value`` strings (``--set``): a dotted scenario key such as
    ``sensors[2].buffer_mbit`` and a TOML value, applied before validation. ``policies``: the
    policies the caller runs instead of the file's own (``--policy``, ``--policies``); a key of
    ``[policy.params]`` may then be any of theirs (:meth:`Scenario.with_policies` shares it out).
    """
    path = Path(spec)
    if not path.exists():
        text = presets().get(str(spec))  # unknown: one line with "did you mean"
        source, base_dir = f"preset {spec}", Path(".")
    else:
        try:
            text = read_text(path, "scenario")
        except SkymuleError as exc:
            raise ScenarioError(str(exc)) from None
        source, base_dir = str(path), path.parent
    data = _toml(text, source)
    for override in overrides:
        data = apply_override(data, override)
    return scenario_from_dict(data, source, base_dir, policies=policies)


def _toml(text: str, source: str) -> dict[str, Any]:
    try:
        return parse_toml(text)
    except ValueError as exc:  # tomllib.TOMLDecodeError, or nested too deeply
        raise ScenarioError(f"{source}: not valid TOML ({exc})") from None
