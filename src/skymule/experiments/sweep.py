"""Sweep files: a base scenario plus axes to vary, expanded into reproducible missions.

A sweep file is TOML::

    base = "paper-sim-fixed"          # preset name or scenario path (relative to this file)
    seed = 1                          # sweep seed: every random draw derives from it
    mode = "product"                  # or mode = { sample = 1000 }

    [axes]
    policy.name = ["greedy", "hgad"]                                  # a list of values
    seed = { range = [0, 1000] }                                      # range(start, stop[, step])
    "sensors[*].buffer_mbit" = { dist = "uniform", low = 200, high = 1500 }  # one draw per sensor
    "sensors[0].x_m" = { dist = "normal", mean = 0, std = 50 }

Axis keys are dotted scenario fields (``sensors[i]`` picks a sensor, ``sensors[*]`` all of
them). ``mode = "product"`` runs the Cartesian product of the list/range axes;
``mode = {sample = N}`` draws N combinations of them at random. ``policy.*`` axes are crossed
with everything else and share the draws: every policy of a combination flies the same
mission. Distribution axes are drawn per combination from a Generator seeded by the sweep
seed and the combination (product mode: its non-policy values; sample mode: its index), so
each mission is reproducible on its own and keeps its draws when other axes grow.

Setting ``x_m``/``y_m`` of a sensor placed by lat/lon first converts it to local metres.

Each mission's id is the first 16 hex digits of the sha256 of the sweep's identity (base
scenario, sweep seed, axis keys and distributions: not the list/range values, so ids survive
growing an axis) followed by the mission's list/range values (plus the sample index in sample
mode): unique per parameter set, stable across runs of the same file, and cheap (one small
``repr`` per mission, no JSON). Missions are planned lazily (:func:`plan_missions`: index, id
and axis values only, a ``range`` axis is never materialised) and resolved into scenario
dictionaries where they run (:class:`Expansion`, which a worker receives once per chunk).
"""

from __future__ import annotations

import functools
import hashlib
import math
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.experiments.distributions import DISTRIBUTIONS, Distribution
from skymule.experiments.fields import (
    Path_,
    assign,
    base_dict,
    canonical,
    column,
    draw_hash,
    draw_seed,
    place_sensors,
    stars,
)
from skymule.experiments.seeding import PCG64Rows, entropy_words
from skymule.io.textfiles import parse_toml, read_text
from skymule.policies.registry import is_plugin
from skymule.scenario import Scenario, load_scenario, policy_shares, scenario_from_dict

TOP_LEVEL_KEYS = ("base", "seed", "mode", "axes")
POLICY_PREFIX = "policy."
_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[(?:\d+|\*)\])*)$")
_INDEX = re.compile(r"\[(\d+|\*)\]")


@dataclass(frozen=True)
class Axis:
    """One varied field: a list of values, or a distribution drawn per combination."""

    key: str
    path: Path_
    values: Sequence[Any] | None = None  # a tuple, or a range (never materialised)
    dist: Distribution | None = None

    @property
    def paired(self) -> bool:
        """Policy axes share the draws of everything else (paired comparisons)."""
        return self.key.startswith(POLICY_PREFIX)


@dataclass(frozen=True)
class SweepSpec:
    """A parsed, validated sweep file."""

    source: str
    base: Scenario
    seed: int
    axes: tuple[Axis, ...]
    sample: int | None
    digest: str = ""  # sha256 of the sweep file's canonical table (see sweep_digest)

    @property
    def discrete(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if a.values is not None)

    @property
    def drawn(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if a.dist is not None)

    @property
    def policy_names(self) -> list[str]:
        """The policies the sweep runs: the ``policy.name`` axis, else the base's policy."""
        return _policy_axis(self.axes) or [self.base.policy.name]

    @property
    def level_columns(self) -> list[str]:
        """The result columns of the list/range axes that are treatments (not seeds, not the
        policy): ``summary.csv`` has one row per policy and combination of them."""
        base = base_dict(self.base)
        columns: list[str] = []
        for axis in self.discrete:
            if axis.key in ("seed", "policy.name") or axis.key.endswith(".seed"):
                continue
            count = stars(axis.path, base)
            columns += [axis.key] if count is None else [column(axis.key, i) for i in range(count)]
        return columns

    def __len__(self) -> int:
        paired = math.prod(len(a.values or ()) for a in self.discrete if a.paired)
        if self.sample is not None:
            return self.sample * paired
        return math.prod(len(a.values or ()) for a in self.discrete)


@dataclass(frozen=True)
class SweepMission:
    """One mission of a sweep: its position, id, axis values and resolved scenario."""

    index: int
    mission_id: str
    params: dict[str, Any]
    scenario: dict[str, Any]


def _fail(source: str, message: str) -> SkymuleError:
    return SkymuleError(f"{source}: {message}")


def parse_key(source: str, key: str) -> Path_:
    """``"sensors[*].buffer_mbit"`` -> ("sensors", "*", "buffer_mbit")."""
    path: list[str | int] = []
    for segment in key.split("."):
        match = _SEGMENT.match(segment)
        if match is None:
            raise _fail(
                source,
                f"axis {key!r} is not a field path; allowed: dotted names with [i] or [*], "
                "e.g. 'policy.name', 'sensors[*].buffer_mbit'",
            )
        path.append(match.group(1))
        for index in _INDEX.findall(match.group(2)):
            path.append("*" if index == "*" else int(index))
    return tuple(path)


def _is_axis_spec(value: Any) -> bool:
    return isinstance(value, list) or (
        isinstance(value, dict) and bool({"values", "range", "dist"} & set(value))
    )


def flatten_axes(table: dict[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """TOML parses ``policy.name = [...]`` as nested tables: flatten them to dotted keys."""
    for key, value in table.items():
        dotted = f"{prefix}.{key}" if prefix else key
        if isinstance(value, dict) and not _is_axis_spec(value):
            yield from flatten_axes(value, dotted)
        else:
            yield dotted, value


def parse_axis(source: str, key: str, value: Any) -> Axis:
    """One ``[axes]`` entry -> :class:`Axis` (raises a one-line SkymuleError)."""
    where = f"axes.{key}"
    path = parse_key(source, key)
    if isinstance(value, list):
        value = {"values": value}
    if not isinstance(value, dict):
        raise _fail(
            source,
            f"{where} = {value!r}; allowed: a list of values, {{range = [start, stop]}} "
            "or {dist = NAME, ...}",
        )
    kinds = [k for k in ("values", "range", "dist") if k in value]
    if len(kinds) != 1:
        raise _fail(source, f"{where}: give exactly one of values, range or dist")
    kind = kinds[0]
    if kind == "values":
        extra = sorted(set(value) - {"values"})
        if extra:
            raise _fail(source, f"{where}: unknown key {extra[0]!r}; allowed: values")
        values = value["values"]
        if not isinstance(values, list) or not values:
            raise _fail(source, f"{where} is empty; give at least one value")
        return Axis(key, path, values=tuple(values))
    if kind == "range":
        bounds = value["range"]
        extra = sorted(set(value) - {"range"})
        if extra:
            raise _fail(source, f"{where}: unknown key {extra[0]!r}; allowed: range")
        if (
            not isinstance(bounds, list)
            or len(bounds) not in (2, 3)
            or not all(isinstance(b, int) and not isinstance(b, bool) for b in bounds)
            or (len(bounds) == 3 and bounds[2] == 0)
        ):
            raise _fail(
                source,
                f"{where}.range = {bounds!r}; allowed: [start, stop] or [start, stop, step] "
                "integers, step != 0",
            )
        values = range(*bounds)  # lazy: {range = [0, 1e9]} costs nothing until it runs
        if not values:
            raise _fail(source, f"{where}.range = {bounds!r} is empty; stop must pass start")
        return Axis(key, path, values=values)
    name = value["dist"]
    kind_spec = DISTRIBUTIONS.get(name) if isinstance(name, str) else None
    if kind_spec is None:
        raise _fail(source, f"{where}.dist = {name!r}; allowed: {', '.join(sorted(DISTRIBUTIONS))}")
    params = {k: v for k, v in value.items() if k != "dist"}
    unknown = sorted(set(params) - set(kind_spec.params))
    missing = [p for p in kind_spec.params if p not in params]
    if unknown or missing:
        problem = f"unknown parameter {unknown[0]!r}" if unknown else f"{missing[0]} is missing"
        raise _fail(
            source,
            f"{where}: {problem}; dist = {name!r} takes {', '.join(kind_spec.params)}",
        )
    invalid = kind_spec.check(params)
    if invalid is not None:
        raise _fail(source, f"{where} (dist = {name!r}): {invalid}")
    return Axis(key, path, dist=Distribution(name, tuple(sorted(params.items()))))


def _parse_mode(source: str, mode: Any) -> int | None:
    if mode == "product":
        return None
    if isinstance(mode, dict) and set(mode) == {"sample"}:
        count = mode["sample"]
        if isinstance(count, int) and not isinstance(count, bool) and count > 0:
            return count
    raise _fail(source, f"mode = {mode!r}; allowed: 'product' or {{sample = N}} with N >= 1")


def _base_scenario(
    source: str, base: Any, folder: Path, policies: list[str] | None = None
) -> Scenario:
    if not isinstance(base, str) or not base:
        raise _fail(source, f"base = {base!r}; allowed: a preset name or a scenario path")
    candidate = folder / base
    return load_scenario(candidate if candidate.exists() else base, policies=policies)


def _policy_axis(axes: Sequence[Axis]) -> list[str] | None:
    """The values of the ``policy.name`` axis (None: the base's own policy runs)."""
    for axis in axes:
        if axis.key == "policy.name" and axis.values is not None:
            return [str(v) for v in axis.values]
    return None


def parse_sweep(data: dict[str, Any], source: str, folder: Path) -> SweepSpec:
    """A sweep from its TOML table; every problem is one line naming the file and field."""
    unknown = sorted(set(data) - set(TOP_LEVEL_KEYS))
    if unknown:
        raise _fail(source, f"unknown key {unknown[0]!r}; allowed: {', '.join(TOP_LEVEL_KEYS)}")
    if "base" not in data:
        raise _fail(source, "base is required (a preset name or a scenario path)")
    seed = data.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise _fail(source, f"seed = {seed!r}; allowed: an integer >= 0")
    sample = _parse_mode(source, data.get("mode", "product"))
    table = data.get("axes", {})
    if not isinstance(table, dict) or not table:
        raise _fail(source, "[axes] is missing or empty; give at least one axis")
    axes = tuple(parse_axis(source, k, v) for k, v in flatten_axes(table))
    base = _base_scenario(source, data["base"], folder, _policy_axis(axes))
    spec = SweepSpec(source, base, seed, axes, sample, sweep_digest(data))
    if sample is None and not spec.discrete:
        raise _fail(
            source,
            "mode = 'product' needs a list or range axis; add one (e.g. seed = {range = "
            "[0, 100]}) or use mode = {sample = N}",
        )
    _check_axes(spec)
    _check_repeats(spec)
    return spec


def sweep_digest(data: dict[str, Any]) -> str:
    """sha256 of a sweep table's canonical JSON: edits to comments or layout keep it."""
    return hashlib.sha256(canonical(data).encode()).hexdigest()


def _check_repeats(spec: SweepSpec) -> None:
    """A value listed twice in one axis would run one mission twice under one id."""
    for axis in spec.discrete:
        if isinstance(axis.values, range):
            continue
        seen: set[str] = set()
        for value in axis.values or ():
            text = repr(value)
            if text in seen:
                raise _fail(
                    spec.source,
                    f"axes.{axis.key} lists {value!r} twice; remove the repeated value",
                )
            seen.add(text)


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep file."""
    file = Path(path)
    try:
        data = parse_toml(read_text(file, "sweep file"))
    except ValueError as exc:  # tomllib.TOMLDecodeError, or nested too deeply
        raise SkymuleError(f"{file}: not valid TOML ({exc})") from None
    return parse_sweep(data, str(file), file.parent)


# --- resolving missions ---------------------------------------------------------------


@dataclass(frozen=True)
class PlannedMission:
    """A mission before it is resolved: position, id and one value per axis (``spec.axes``)."""

    index: int
    mission_id: str
    values: tuple[Any, ...]


@dataclass(frozen=True)
class Expansion:
    """Everything needed to turn a :class:`PlannedMission` into a scenario (small, picklable).

    A worker receives it once per chunk, with the planned missions: the base scenario travels
    once, each mission only as its axis values.
    """

    source: str
    base_dir: str
    base: dict[str, Any]
    axes: tuple[Axis, ...]
    counts: tuple[int | None, ...]  # elements each "*" axis spans (None: no "*")
    shares: tuple[tuple[str, frozenset[str] | None], ...] = ()
    """The ``[policy.params]`` keys each policy of the sweep keeps (None: all)."""

    def scenario(self, values: Sequence[Any]) -> dict[str, Any]:
        """The resolved scenario dictionary of a mission (its policy's parameters only)."""
        data = self.base
        for axis, count, value in zip(self.axes, self.counts, values, strict=True):
            if count is not None and axis.values is not None:
                value = [value] * count
            data = assign(data, axis.path, value, self.source, axis.key)
        return place_sensors(share_params(data, dict(self.shares)))

    def scenario_with(self, data: dict[str, Any], axis: Axis, value: Any) -> dict[str, Any]:
        """``data`` (a base or resolved dict) with one list/range axis set to ``value``."""
        count = stars(axis.path, data)
        value = value if count is None else [value] * count
        return assign(data, axis.path, value, self.source, axis.key)

    def placed(self, data: dict[str, Any]) -> dict[str, Any]:
        """``data`` with sensors given x_m/y_m by an axis turned into local metres."""
        return place_sensors(data)

    def params(self, values: Sequence[Any]) -> dict[str, Any]:
        """Axis values by column (``sensors[*]`` axes get one column per sensor)."""
        params: dict[str, Any] = {}
        for axis, count, value in zip(self.axes, self.counts, values, strict=True):
            if count is None:
                params[axis.key] = value
            elif axis.values is not None:
                params.update({column(axis.key, i): value for i in range(count)})
            else:
                params.update({column(axis.key, i): v for i, v in enumerate(value)})
        return params

    def validate(self, mission: PlannedMission) -> Scenario:
        """The mission's scenario, validated; errors name the sweep file and mission values."""
        data = self.scenario(mission.values)
        try:
            return scenario_from_dict(data, self.source, Path(self.base_dir))
        except SkymuleError:  # again, with the mission named (built only when needed)
            shown = ", ".join(f"{k} = {v!r}" for k, v in self.params(mission.values).items())
            source = f"{self.source} (mission {mission.index}: {shown})"
            if len(source) > 200:
                source = f"{self.source} (mission {mission.index})"
            return scenario_from_dict(data, source, Path(self.base_dir))


def share_params(data: dict[str, Any], shares: dict[str, frozenset[str] | None]) -> dict[str, Any]:
    """``data`` with ``[policy.params]`` cut to the keys its policy keeps (``shares``; a
    policy not in it keeps everything)."""
    policy = data.get("policy")
    if not isinstance(policy, dict) or not isinstance(policy.get("params"), dict):
        return data
    keep = shares.get(str(policy.get("name")))
    if keep is None:
        return data
    params = {k: v for k, v in policy["params"].items() if k in keep}
    return {**data, "policy": {**policy, "params": params}}


def expansion(spec: SweepSpec) -> Expansion:
    """The sweep's :class:`Expansion`, for running it: the plug-ins among its policies are
    imported (to share ``[policy.params]`` out, and refuse a key none of its policies has)."""
    base = base_dict(spec.base)
    counts = tuple(stars(axis.path, base) for axis in spec.axes)
    shares = tuple(zip(spec.policy_names, _shares(spec), strict=True))
    return Expansion(spec.source, spec.base.base_dir, base, spec.axes, counts, shares)


def _shares(spec: SweepSpec) -> list[frozenset[str] | None]:
    """:func:`policy_shares` of the sweep's policies over the base's ``[policy.params]`` and
    the ``policy.params.*`` axes (imports the plug-ins among them)."""
    params = (a.path[2] for a in spec.axes if a.path[:2] == ("policy", "params"))
    keys = dict.fromkeys([*spec.base.policy.params, *map(str, params)])
    try:
        return policy_shares(keys, spec.policy_names, spec.base.policy.name)
    except SkymuleError as exc:
        raise _fail(spec.source, str(exc)) from None


def _id_prefix(spec: SweepSpec, base: dict[str, Any]) -> bytes:
    """What every id of the sweep hashes first: all but the list/range values."""
    identity = {
        "base": base,
        "seed": spec.seed,
        "axes": [
            [a.key, None if a.dist is None else [a.dist.name, a.dist.params]] for a in spec.axes
        ],
    }
    return hashlib.sha256(canonical(identity).encode()).digest()


def _lazy_product(sequences: Sequence[Sequence[Any]]) -> Iterator[tuple[Any, ...]]:
    """``itertools.product`` without copying its inputs (which would materialise a range)."""
    if not sequences:
        yield ()
        return
    for head in sequences[0]:
        for rest in _lazy_product(sequences[1:]):
            yield (head, *rest)


def _digits(number: int, radices: Sequence[int]) -> list[int]:
    """``number`` in the mixed radix ``radices`` (the last digit varies fastest)."""
    digits = [0] * len(radices)
    for j in range(len(radices) - 1, -1, -1):
        number, digits[j] = divmod(number, radices[j])
    return digits


@dataclass(frozen=True)
class SweepPlan:
    """A sweep's missions in run order, any range of them on demand (small, picklable).

    The run order puts the ``policy.*`` values of one combination next to each other, so the
    missions that share a built track and draws fall into one chunk; a mission's ``index`` is
    its position in the file's order (product mode: the last axis varies fastest). A worker
    gets the plan once and each chunk as a range of run positions (:meth:`missions`): nothing
    per mission travels, and the sweep process maps positions to indices without planning a
    mission (:meth:`indices`).
    """

    resolve: Expansion
    seed: int
    sample: int | None
    prefix: bytes  # sha256 of the sweep identity (see _id_prefix)

    @property
    def discrete(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.resolve.axes if a.values is not None)

    @property
    def _sizes(self) -> list[int]:
        return [len(a.values or ()) for a in self.discrete]

    @property
    def _outer(self) -> list[int]:
        return [i for i, a in enumerate(self.discrete) if not a.paired]

    @property
    def _inner(self) -> list[int]:
        return [i for i, a in enumerate(self.discrete) if a.paired]

    @property
    def _strides(self) -> list[int]:
        sizes = self._sizes
        return [math.prod(sizes[i + 1 :]) for i in range(len(sizes))]

    @property
    def has_draws(self) -> bool:
        return any(a.dist is not None for a in self.resolve.axes)

    @property
    def paired_count(self) -> int:
        """Missions per combination of the non-policy values (one per policy combination)."""
        sizes = self._sizes
        return math.prod(sizes[i] for i in self._inner)

    def __len__(self) -> int:
        if self.sample is not None:
            return self.sample * self.paired_count
        return math.prod(self._sizes)

    @functools.cached_property
    def _drawn_axes(self) -> tuple[tuple[str, Distribution, int | None], ...]:
        return tuple(
            (axis.key, axis.dist, count)
            for axis, count in zip(self.resolve.axes, self.resolve.counts, strict=True)
            if axis.dist is not None
        )

    @functools.cached_property
    def _all_uniform(self) -> bool:
        """True when the sweep draws, and only from uniform distributions (drawn over arrays)."""
        axes = self._drawn_axes
        return bool(axes) and all(dist.name == "uniform" for _, dist, _ in axes)

    def draws(self, rng: np.random.Generator) -> dict[str, Any]:
        """One combination's draws of every distribution axis."""
        values: dict[str, Any] = {}
        for key, dist, count in self._drawn_axes:
            drawn = dist.draw(rng, count or 1)
            values[key] = drawn if count is not None else drawn[0]
        return values

    def planned(
        self, index: int, chosen: dict[str, Any], drawn: dict[str, Any], key: Any
    ) -> PlannedMission:
        every = {**chosen, **drawn}
        digest = hashlib.sha256(self.prefix + repr(key).encode()).hexdigest()[:16]
        return PlannedMission(index, digest, tuple(every[a.key] for a in self.resolve.axes))

    def missions(self, start: int = 0, stop: int | None = None) -> Iterator[PlannedMission]:
        """The missions at run positions ``start`` to ``stop`` (default: the end), lazily."""
        stop = len(self) if stop is None else min(stop, len(self))
        if start >= stop:
            return
        if self.sample is None:
            yield from self._product(start, stop)
        else:
            yield from self._sampled(start, stop)

    def _product(self, start: int, stop: int) -> Iterator[PlannedMission]:
        discrete, sizes, strides = self.discrete, self._sizes, self._strides
        outer, inner = self._outer, self._inner
        per = self.paired_count
        combos: list[tuple[int, list[Any], int]] = []
        for number in range(start // per, (stop - 1) // per + 1):
            combo: list[Any] = [None] * len(discrete)
            first = 0
            for i, d in zip(outer, _digits(number, [sizes[i] for i in outer]), strict=True):
                combo[i] = (discrete[i].values or ())[d]
                first += d * strides[i]
            combos.append((number, combo, first))
        keys = [[combo[i] for i in outer] for _, combo, _ in combos]
        together = self._combination_draws(keys) if self.has_draws else None
        for k, ((number, combo, first), key) in enumerate(zip(combos, keys, strict=True)):
            drawn = {}
            if together is not None:
                drawn = together[k]
            elif self.has_draws:
                drawn = self.draws(draw_seed(self.seed, key))
            for position in range(max(start, number * per), min(stop, (number + 1) * per)):
                index = first
                digits = _digits(position - number * per, [sizes[i] for i in inner])
                for i, d in zip(inner, digits, strict=True):
                    combo[i] = (discrete[i].values or ())[d]
                    index += d * strides[i]
                chosen = {a.key: v for a, v in zip(discrete, combo, strict=True)}
                yield self.planned(index, chosen, drawn, tuple(combo))

    def _sampled(self, start: int, stop: int) -> Iterator[PlannedMission]:
        assert self.sample is not None
        discrete = self.discrete
        paired = [a for a in discrete if a.paired]
        unpaired = [a for a in discrete if not a.paired]
        per = self.paired_count
        replicas = range(start // per, (stop - 1) // per + 1)
        together = self._uniform_draws(replicas)
        for number, replica in enumerate(replicas):
            chosen = {}
            if unpaired:  # a Generator costs ~30 us: only made when there is something to pick
                picks = np.random.default_rng([self.seed, replica])
                chosen = {
                    a.key: (a.values or ())[int(picks.integers(len(a.values or ())))]
                    for a in unpaired
                }
            drawn = {}
            if together is not None:
                drawn = together[number]
            elif self.has_draws:
                drawn = self.draws(np.random.default_rng([self.seed, replica, 1]))
            for position in range(max(start, replica * per), min(stop, (replica + 1) * per)):
                digits = _digits(position - replica * per, [len(a.values or ()) for a in paired])
                values = [(a.values or ())[d] for a, d in zip(paired, digits, strict=True)]
                both = {**chosen, **{a.key: v for a, v in zip(paired, values, strict=True)}}
                key = (replica, tuple(both[a.key] for a in discrete))
                yield self.planned(position, both, drawn, key)

    def _uniform_draws(self, replicas: range) -> list[dict[str, Any]] | None:
        """:meth:`draws` of each replica's Generator (``default_rng([seed, replica, 1])``),
        all at once; None: draw replica by replica (:meth:`_draws_of`)."""
        if not self._all_uniform or not replicas or replicas[-1] >= 2**32:
            return None  # (a replica from 2**32 on is two entropy words)
        words = np.empty((len(replicas), len(entropy_words(self.seed)) + 2), np.uint32)
        words[:, :-2] = entropy_words(self.seed)
        words[:, -2] = np.arange(replicas.start, replicas.stop, dtype=np.uint32)
        words[:, -1] = 1
        return self._draws_of(words)

    def _combination_draws(self, keys: Sequence[Any]) -> list[dict[str, Any]] | None:
        """:meth:`draws` of each combination's Generator (:func:`draw_seed` of its key), all
        at once; None: draw combination by combination (:meth:`_draws_of`)."""
        if not self._all_uniform:
            return None
        hashes = [draw_hash(key) for key in keys]
        if not hashes or min(hashes) < 2**32:  # two entropy words a hash (else one)
            return None
        values = np.array(hashes, np.uint64)
        words = np.empty((len(keys), len(entropy_words(self.seed)) + 2), np.uint32)
        words[:, :-2] = entropy_words(self.seed)
        words[:, -2] = (values & np.uint64(0xFFFFFFFF)).astype(np.uint32)
        words[:, -1] = (values >> np.uint64(32)).astype(np.uint32)
        return self._draws_of(words)

    def _draws_of(self, words: np.ndarray) -> list[dict[str, Any]] | None:
        """:meth:`draws` of the Generators seeded by each row of entropy ``words``, all at
        once over arrays (:class:`~skymule.experiments.seeding.PCG64Rows`, the same numbers,
        ~0.1 us a value instead of ~10 us a Generator): when every distribution axis is
        uniform; None otherwise."""
        if not self._all_uniform:
            return None
        rows = PCG64Rows(words)
        columns = []
        for _, dist, count in self._drawn_axes:
            params = dict(dist.params)
            drawn = rows.uniform(params["low"], params["high"], count or 1).tolist()
            columns.append(drawn if count is not None else [row[0] for row in drawn])
        names = [key for key, _, _ in self._drawn_axes]
        return [dict(zip(names, values, strict=True)) for values in zip(*columns, strict=True)]

    def indices(self, start: int, stop: int) -> np.ndarray:
        """Mission indices at run positions ``start`` to ``stop`` (int64, no mission planned)."""
        positions = np.arange(start, min(stop, len(self)), dtype=np.int64)
        if self.sample is not None:
            return positions  # replica-major with the policies innermost: the file's order
        sizes, strides = self._sizes, self._strides
        per = self.paired_count
        index = np.zeros_like(positions)
        for axes, numbers in ((self._outer, positions // per), (self._inner, positions % per)):
            for i in reversed(axes):
                numbers, digit = np.divmod(numbers, sizes[i])
                index += digit * strides[i]
        return index


def sweep_plan(spec: SweepSpec) -> SweepPlan:
    """The plan of ``spec`` (what a worker needs to plan and resolve any of its missions)."""
    resolve = expansion(spec)
    return SweepPlan(resolve, spec.seed, spec.sample, _id_prefix(spec, resolve.base))


def plan_missions(spec: SweepSpec, *, paired_last: bool = False) -> Iterator[PlannedMission]:
    """Every mission of the sweep, lazily (memory does not grow with it).

    In index order, or with ``paired_last`` in run order (:class:`SweepPlan`); ``index`` is
    the position in the file's order either way.
    """
    plan = sweep_plan(spec)
    if paired_last or spec.sample is not None:  # sample mode: run order is the file's order
        yield from plan.missions()
        return
    discrete = spec.discrete
    unpaired_at = [i for i, a in enumerate(discrete) if not a.paired]
    for index, combo in enumerate(_lazy_product([a.values or () for a in discrete])):
        chosen: dict[str, Any] = {a.key: v for a, v in zip(discrete, combo, strict=True)}
        drawn = {}
        if spec.drawn:
            drawn = plan.draws(draw_seed(spec.seed, [combo[i] for i in unpaired_at]))
        yield plan.planned(index, chosen, drawn, combo)


def iter_missions(spec: SweepSpec) -> Iterator[SweepMission]:
    """Every mission of the sweep, resolved, in a fixed order (lazily)."""
    resolve = expansion(spec)
    for mission in plan_missions(spec):
        yield SweepMission(
            mission.index,
            mission.mission_id,
            resolve.params(mission.values),
            resolve.scenario(mission.values),
        )


def validate_mission(spec: SweepSpec, mission: SweepMission) -> Scenario:
    """The mission's scenario, validated; errors name the sweep file and mission values."""
    shown = ", ".join(f"{k} = {v!r}" for k, v in mission.params.items())
    source = f"{spec.source} (mission {mission.index}: {shown})"
    if len(source) > 200:
        source = f"{spec.source} (mission {mission.index})"
    return scenario_from_dict(mission.scenario, source, Path(spec.base.base_dir))


def _check_axes(spec: SweepSpec) -> None:
    """Each axis alone, on the base: names the axis when a field is unknown or a value bad."""
    from skymule.policies import POLICIES, unknown_policies

    base = base_dict(spec.base)
    # which policy keeps which [policy.params] key is known without importing anything when
    # the sweep runs no plug-in; else it is checked when the sweep runs (expansion)
    unknown = unknown_policies(spec.policy_names)
    if unknown:
        raise _fail(
            spec.source,
            f"axes.policy.name value {unknown[0]!r} is not a policy; "
            f"allowed: {', '.join(sorted(POLICIES))}",
        )
    plugins = any(is_plugin(name) for name in spec.policy_names)
    registered = {} if plugins else dict(zip(spec.policy_names, _shares(spec), strict=True))
    for axis in spec.axes:
        count = stars(axis.path, base)
        candidates: Iterable[Any] = [None]  # distributions: checked on their draws
        if isinstance(axis.values, range):
            candidates = {axis.values[0], axis.values[-1]}  # integers: the extremes suffice
        elif axis.values is not None:
            candidates = axis.values
        for value in candidates:
            if axis.dist is not None:
                value = axis.dist.draw(np.random.default_rng(0), count or 1)
                value = value if count is not None else value[0]
            elif count is not None:
                value = [value] * count
            data = place_sensors(assign(base, axis.path, value, spec.source, axis.key))
            scenario_from_dict(
                share_params(data, registered),
                f"{spec.source}: axes.{axis.key}",
                Path(spec.base.base_dir),
                policies=spec.policy_names,
            )
