"""Output folders: never silently overwrite or mix one kind of result with another.

A non-empty ``--out`` is written to only when it already holds the same thing (a run of the
same policy and scenario, a comparison of the same scenario and policies, a bound of the
same scenario, a sweep); anything else is one line and exit 2 unless ``--force``. Which
sweep a sweep folder holds is the store's business (``sweep.json``, see
:mod:`skymule.experiments.store`): it refuses another sweep file, in one line.
"""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from skymule.errors import SkymuleError

SWEEP_FILES = ("sweep.json", "results", "results.parquet", "summary.csv", ".lock")
"""What a sweep folder holds (``skymule.experiments.store``)."""

SIM2REAL_FILE = "sim2real.json"
"""What marks a ``skymule sim2real --out`` folder (``skymule.tasks.sim2real``)."""


@dataclass(frozen=True)
class Holds:
    """What an output folder holds: its kind and, where known, scenario and policies."""

    kind: str  # "empty", "run", "compare", "bound", "sweep", "sim2real" or "other"
    scenario: str | None = None
    policies: tuple[str, ...] = ()

    def describe(self) -> str:
        if self.kind == "run":
            return f"a run of policy {self.policies[0]!r} on scenario {self.scenario!r}"
        if self.kind == "compare":
            return f"a comparison of {', '.join(self.policies)} on scenario {self.scenario!r}"
        if self.kind == "bound":
            return f"the bound of scenario {self.scenario!r}"
        if self.kind == "sweep":
            return "a sweep"
        if self.kind == "sim2real":
            return "a sim2real comparison"
        return "other files"


def _read_json(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _comparison(path: Path) -> tuple[str | None, tuple[str, ...]]:
    try:
        with path.open(newline="") as handle:
            rows = list(csv.DictReader(handle))
    except (OSError, csv.Error, UnicodeDecodeError):
        return None, ()
    scenarios = {r.get("scenario") for r in rows}
    scenario = scenarios.pop() if len(scenarios) == 1 else None
    return scenario, tuple(r.get("policy") or "" for r in rows)


def inspect_folder(out: Path) -> Holds:
    """What ``out`` holds (``empty`` when missing or empty)."""
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return Holds("empty")
    if not out.is_dir():
        return Holds("other")
    if any((out / name).exists() for name in SWEEP_FILES):
        return Holds("sweep")
    if (out / SIM2REAL_FILE).exists():
        return Holds("sim2real")
    if (out / "comparison.csv").exists():
        scenario, policies = _comparison(out / "comparison.csv")
        return Holds("compare", scenario, policies)
    if (out / "summary.json").exists():
        summary = _read_json(out / "summary.json")
        return Holds("run", summary.get("scenario"), (str(summary.get("policy")),))
    if (out / "bound.json").exists():
        return Holds("bound", _read_json(out / "bound.json").get("scenario"))
    return Holds("other")


def _refuse(out: Path, holds: Holds, wanted: str) -> SkymuleError:
    return SkymuleError(
        f"--out {out}: holds {holds.describe()}, not {wanted}; "
        "choose another folder or add --force to write over it"
    )


def guard_run(out: Path, scenario: str, policy: str, force: bool) -> None:
    holds = inspect_folder(out)
    if force or holds.kind == "empty" or holds == Holds("run", scenario, (policy,)):
        return
    raise _refuse(out, holds, f"a run of policy {policy!r} on scenario {scenario!r}")


def guard_compare(out: Path, scenario: str, policies: list[str], force: bool) -> None:
    holds = inspect_folder(out)
    if force or holds.kind == "empty":
        return
    same = holds.kind == "compare" and holds.scenario == scenario
    if same and (set(policies) <= set(holds.policies) or not holds.policies):
        return  # the same comparison again
    raise _refuse(out, holds, f"a comparison of {', '.join(policies)} on scenario {scenario!r}")


def guard_analysis(out: Path, force: bool) -> None:
    holds = inspect_folder(out)
    if force or holds.kind in ("empty", "compare"):
        return
    raise _refuse(out, holds, "a replay (compare folder)")


def guard_bound(out: Path, scenario: str, force: bool) -> None:
    holds = inspect_folder(out)
    if force or holds.kind == "empty":
        return
    if holds.kind in ("bound", "compare") and holds.scenario == scenario:
        return
    raise _refuse(out, holds, f"the bound of scenario {scenario!r}")


def guard_sim2real(out: Path, force: bool) -> None:
    """Refuse a folder that holds anything but a sim2real comparison (unless ``--force``)."""
    holds = inspect_folder(out)
    if force or holds.kind in ("empty", "sim2real"):
        return
    raise _refuse(out, holds, "a sim2real comparison")


def guard_sweep(out: Path, sweep_file: Path, force: bool) -> None:
    """Refuse a folder that holds anything but a sweep; with ``--force``, clear it first.

    A sweep folder of another sweep file is refused by the store itself (its ``sweep.json``),
    unless ``--force`` cleared it here.
    """
    holds = inspect_folder(out)
    if holds.kind == "empty":
        return
    if not force:
        if holds.kind != "sweep":
            raise _refuse(out, holds, f"a sweep of {sweep_file}")
        return
    if holds.kind == "sweep":
        for name in SWEEP_FILES:
            path = out / name
            if path.is_dir():
                shutil.rmtree(path)
            elif path.exists():
                path.unlink()
