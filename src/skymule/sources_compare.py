"""The same scenario, policy and path under several signal sources (``compare --sources``).

A source spec is a path-loss model name (``fspl``, ``log-distance``, ``al-hourani``, ...: the
scenario with ``[radio] model`` set to it and ``[signal] source = "model"``), ``radiomap:FILE``
(a fitted map) or ``scenario`` (the scenario as written). Everything else in the scenario
(sensors, path, link budget, shadowing/fading settings, seed) stays the same.
"""

from __future__ import annotations

import re
from pathlib import Path

from skymule.errors import SkymuleError
from skymule.radio.sources import PATHLOSS_BUILDERS
from skymule.runner import RunResult, simulate
from skymule.scenario import Scenario
from skymule.world import build_mission


def source_variant(base: Scenario, spec: str) -> Scenario:
    """The scenario ``base`` with its signal source replaced as ``spec`` says."""
    spec = spec.strip()
    signal = base.signal
    if spec == "scenario":
        return base
    if spec.startswith("radiomap:") and spec[len("radiomap:") :]:
        path = str(Path(spec[len("radiomap:") :]).resolve())
        update = {"source": "radiomap", "map": path, "traces": None, "trace": None}
        return base.model_copy(update={"signal": signal.model_copy(update=update)})
    if spec in PATHLOSS_BUILDERS:
        radio = base.radio.model_copy(update={"model": spec})
        update = {"source": "model", "map": None, "traces": None, "trace": None}
        return base.model_copy(update={"radio": radio, "signal": signal.model_copy(update=update)})
    raise SkymuleError(
        f"--sources: {spec!r} is not allowed; use path-loss models "
        f"({', '.join(sorted(PATHLOSS_BUILDERS))}), radiomap:FILE.json or scenario"
    )


def folder_name(spec: str) -> str:
    """A file-system-safe folder name for a source spec."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", spec.strip()).strip("_") or "source"


def parse_sources(text: str) -> list[str]:
    specs = [s.strip() for s in text.split(",") if s.strip()]
    if not specs:
        raise SkymuleError("--sources is empty; give e.g. fspl,log-distance,radiomap:map.json")
    return specs


def compare_sources(
    base: Scenario, specs: list[str], policies: list[str]
) -> list[tuple[str, str, RunResult]]:
    """(source spec, policy, result) for every source x policy; policies share one mission."""
    variants = [(spec, source_variant(base, spec)) for spec in specs]  # validate all first
    results = []
    for spec, scenario in variants:
        mission = build_mission(scenario)
        for policy in policies:
            results.append((spec, policy, simulate(scenario, policy, mission=mission)))
    return results
