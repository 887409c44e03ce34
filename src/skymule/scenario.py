"""Scenario files: a validated, serialisable description of one mission.

A scenario is TOML (see the README for the schema). It is validated by pydantic models that
forbid unknown keys, so a misspelt field is an error, never silently ignored. Mbit and lat/lon
appear here, at the edge; :mod:`skymule.world` turns a scenario into SI arrays.

Built-in presets live in ``skymule/scenarios/*.toml`` and resolve by name wherever a scenario
path is accepted.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from skymule.errors import ScenarioError

PositiveFloat = Annotated[float, Field(gt=0)]


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class LatLon(_Spec):
    lat: Annotated[float, Field(ge=-90, le=90)]
    lon: Annotated[float, Field(ge=-180, le=180)]


class MissionSpec(_Spec):
    duration_s: PositiveFloat | None = None
    """Mission time T*slot_s [s]; omitted for a trace source means the trace's length."""
    slot_s: PositiveFloat = 1.0
    """Slot length [s]."""
    aadm_window_s: PositiveFloat | None = None
    """Close the download window this long after the start [s], as the AADM controller does
    at 500 s: later slots serve nothing. None: downloads count until the mission ends."""


class SiteSpec(_Spec):
    origin: LatLon = LatLon(lat=35.7274824, lon=-78.6962749)
    """Origin of the local east/north frame (default: the AADM launch point)."""
    geofence: str | None = None
    """Built-in site name (``lake-wheeler``) or a KML/GeoJSON path; optional."""


class SensorSpec(_Spec):
    name: Annotated[str, Field(min_length=1)]
    lat: Annotated[float, Field(ge=-90, le=90)] | None = None
    lon: Annotated[float, Field(ge=-180, le=180)] | None = None
    x_m: float | None = None
    y_m: float | None = None
    height_m: float = 10.0
    """Antenna height [m] relative to the take-off ground."""
    buffer_mbit: Annotated[float, Field(ge=0)]

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
    """Path-loss model name (see ``skymule.radio.pathloss``)."""
    frequency_hz: PositiveFloat = 3.41e9
    tx_power_dbm: float = 10.0
    tx_gain_dbi: float = 10.0
    rx_gain_dbi: float = 2.0
    noise_dbm: float = -90.0
    bandwidth_hz: PositiveFloat = 1.4e6
    rate_table: str = "aadm-lte-cqi"
    path_loss_exponent: PositiveFloat = 2.0
    """log-distance: path-loss exponent n."""
    reference_distance_m: PositiveFloat = 1.0
    """log-distance: reference distance d0 [m]."""
    reference_loss_db: float | None = None
    """log-distance: loss at d0 [dB]; default free space at d0."""
    ground_reflection: Annotated[float, Field(ge=-1, le=1)] = -1.0
    """two-ray: ground reflection coefficient Gamma (-1: perfect reflector, grazing)."""
    environment: Literal["suburban", "urban", "dense-urban", "high-rise-urban"] = "suburban"
    """al-hourani: built-up environment (Al-Hourani et al. 2014, Table I)."""
    shadowing_std_db: Annotated[float, Field(ge=0, le=30)] = 0.0
    """Log-normal shadowing standard deviation [dB] (0: none); model sources only."""
    shadowing_decorrelation_m: PositiveFloat = 50.0
    """Shadowing decorrelation distance d_corr [m] (Gudmundson: rho(d) = exp(-d / d_corr))."""
    fading: Literal["none", "rician", "rayleigh"] = "none"
    """Small-scale fading, drawn per slot and sensor."""
    rician_k_db: Annotated[float, Field(ge=-30, le=40)] = 10.0
    """rician: K factor [dB] (power of the specular part over the scattered part)."""


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
    waypoints: list[list[float]] | str | None = None
    """Fixed path: [[x, y, z], ...] metres, or a CSV path (x_m,y_m,z_m or lat,lon,alt)."""
    speed_mps: PositiveFloat = 10.0
    """Nominal speed along a fixed path [m/s]."""
    home: LatLon | list[float] | None = None
    """Autonomous: home point, lat/lon or [x, y] metres (default: the site origin)."""
    altitude_m: PositiveFloat = 30.0
    """Autonomous: flight altitude [m]."""
    max_speed_mps: PositiveFloat = 10.0
    return_home: bool = True
    visit_radius_m: PositiveFloat = 50.0


class PolicySpec(_Spec):
    name: str = "hgad"
    hover_threshold: Annotated[float, Field(gt=0, le=1)] = 1.0
    """HGAD: fraction of the peak rate that triggers a hover."""
    max_hover_s: PositiveFloat = 60.0
    """HGAD: longest hover [s]."""


class UavSpec(_Spec):
    """One UAV of a fleet (``[[uavs]]``); unset fields come from ``[trajectory]``/``[policy]``."""

    name: Annotated[str, Field(min_length=1)]
    home: LatLon | list[float] | None = None
    """Home point, lat/lon or [x, y] metres (default: ``trajectory.home``)."""
    altitude_m: PositiveFloat | None = None
    """Autonomous flight altitude [m] (default: ``trajectory.altitude_m``)."""
    max_speed_mps: PositiveFloat | None = None
    """Speed cap (autonomous) or speed along the path (fixed) [m/s]."""
    waypoints: list[list[float]] | str | None = None
    """Fixed path of this UAV (as ``trajectory.waypoints``)."""
    policy: PolicySpec | None = None
    """This UAV's own policy (default: the scenario's ``[policy]``)."""


class Scenario(_Spec):
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
    uavs: list[UavSpec] | None = None
    """Several UAVs sharing the sensors' buffers (``docs/fleet.md``); None: one UAV."""
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

    def resolve_path(self, value: str) -> Path:
        path = Path(value)
        return path if path.is_absolute() else Path(self.base_dir) / path

    def with_policy(self, name: str) -> Scenario:
        return self.model_copy(update={"policy": self.policy.model_copy(update={"name": name})})

    def to_toml_dict(self) -> dict[str, Any]:
        return self.model_dump(mode="json", exclude_none=True)


def _location(loc: tuple[int | str, ...]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif not str(part).startswith("function-") and part not in ("list[float]", "str"):
            text += f".{part}" if text else str(part)
    return text


def format_validation_error(source: str, error: ValidationError) -> str:
    """The first validation problem as one line: ``source: field = value: what is allowed``."""
    first = error.errors()[0]
    where = _location(tuple(first["loc"]))
    message = first["msg"].removeprefix("Value error, ")
    if first["type"] == "extra_forbidden":
        return f"{source}: unknown field {where!r}; check its spelling against the schema"
    if first["type"] == "missing":
        return f"{source}: {where} is required"
    value = first.get("input")
    shown = "" if isinstance(value, dict) else f" = {value!r}"
    return f"{source}: {where or 'scenario'}{shown}: {message}"


def scenario_from_dict(data: dict[str, Any], source: str, base_dir: Path) -> Scenario:
    try:
        return Scenario.model_validate({**data, "base_dir": str(base_dir)})
    except ValidationError as exc:
        raise ScenarioError(format_validation_error(source, exc)) from None


def preset_names() -> list[str]:
    """Names of the built-in scenario presets."""
    folder = resources.files("skymule").joinpath("scenarios")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_scenario(spec: str | Path) -> Scenario:
    """Load a scenario from a TOML path or a built-in preset name."""
    path = Path(spec)
    if not path.exists() and str(spec) in preset_names():
        resource = resources.files("skymule").joinpath("scenarios", f"{spec}.toml")
        text = resource.read_text()
        return _parse(text, f"preset {spec}", Path("."))
    if not path.exists():
        raise ScenarioError(
            f"scenario {str(spec)!r}: no such file and not a preset "
            f"(presets: {', '.join(preset_names())})"
        )
    try:
        text = path.read_text()
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read ({exc.strerror})") from None
    return _parse(text, str(path), path.parent)


def _parse(text: str, source: str, base_dir: Path) -> Scenario:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: not valid TOML ({exc})") from None
    return scenario_from_dict(data, source, base_dir)
