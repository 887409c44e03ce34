"""``skymule``'s public API: what a user imports, from one place, loaded when first used."""

from __future__ import annotations

import ast
import importlib
import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

import skymule

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def python_blocks(page: Path) -> list[tuple[int, str]]:
    """(line, code) of every ```python (or ```py) block of ``page``."""
    text = page.read_text()
    return [
        (text.count("\n", 0, match.start()) + 2, match.group(1))
        for match in re.finditer(r"^```(?:python|py)\n(.*?)^```", text, flags=re.S | re.M)
    ]


def public_names(module: str) -> set[str]:
    """What ``module`` exports: ``skymule.__all__``, or the ``__all__`` of a module that declares
    one (a module without ``__all__`` is internal: nothing in it is public)."""
    found = importlib.import_module(module)
    return set(getattr(found, "__all__", ()))


def non_public_imports(code: str) -> list[str]:
    """The skymule names ``code`` imports or reaches (``skymule.X``) that are not public."""
    bad = []
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "skymule":
            exported = public_names(node.module or "")
            bad += [f"{node.module}.{a.name}" for a in node.names if a.name not in exported]
        elif isinstance(node, ast.Import):
            bad += [
                a.name
                for a in node.names
                if a.name.startswith("skymule.") and not public_names(a.name)
            ]
        elif (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id == "skymule"
            and node.attr not in skymule.__all__
        ):
            bad.append(f"skymule.{node.attr}")
    return bad


def test_docs_import_only_public_names() -> None:
    """Every import in the Python blocks of README.md and docs/*.md is public: exported from
    ``skymule`` or listed in the ``__all__`` of its module (a user copies these lines)."""
    pytest.importorskip("pettingzoo", reason="docs/fleet.md imports the PettingZoo env")
    found = []
    for page in PAGES:
        for line, code in python_blocks(page):
            found += [f"{page.name}:{line}: {name}" for name in non_public_imports(code)]
    assert not found, "README/docs import names skymule does not export:\n" + "\n".join(found)


def test_the_docs_check_catches_an_internal_import() -> None:
    assert non_public_imports("from skymule.tasks.compare import write_compare") == [
        "skymule.tasks.compare.write_compare"
    ]
    assert non_public_imports("import skymule\nskymule.run_fixed()") == ["skymule.run_fixed"]
    assert non_public_imports("import skymule.tasks.compare") == ["skymule.tasks.compare"]
    assert non_public_imports("from skymule import write_compare, scenario_bound") == []


def _documented(cls: type, name: str, member: object) -> bool:
    """A public method has a docstring; a property has one or is listed under the class
    docstring's ``Attributes:``."""
    if isinstance(member, property):
        listed = re.search(rf"^\s+{name}:", cls.__doc__ or "", flags=re.M) is not None
        return bool(member.fget and member.fget.__doc__) or listed
    function = getattr(member, "__func__", member)
    return not inspect.isfunction(function) or bool(function.__doc__)


def test_every_export_and_its_public_methods_are_documented() -> None:
    missing = []
    for name in skymule.__all__:
        value = getattr(skymule, name)
        if not inspect.getdoc(value):
            missing.append(name)
        if inspect.isclass(value) and value.__module__.startswith("skymule"):
            missing += [
                f"{name}.{attr}"
                for attr, member in vars(value).items()
                if not attr.startswith("_") and not _documented(value, attr, member)
            ]
    assert not missing, f"no docstring: {missing}"


def test_every_exported_name_resolves_and_is_documented() -> None:
    assert skymule.__all__ == sorted(skymule.__all__)
    for name in skymule.__all__:
        value = getattr(skymule, name)
        assert getattr(value, "__doc__", None), name
    with pytest.raises(AttributeError, match="no attribute 'run_fixed'"):
        skymule.run_fixed  # noqa: B018


def test_the_policy_protocols_document_their_methods() -> None:
    for protocol in (skymule.Policy, skymule.BatchPolicy):
        for method in ("reset", "act"):
            assert getattr(protocol, method).__doc__, (protocol, method)


def test_the_environments_document_reset_and_step() -> None:
    pytest.importorskip("gymnasium", reason="the environments need gymnasium (test extra)")
    from skymule.envs.datamule import DataMuleEnv
    from skymule.envs.vector import DataMuleVectorEnv

    for env in (DataMuleEnv, DataMuleVectorEnv):
        for method in ("reset", "step"):
            assert getattr(env, method).__doc__ != getattr(env.__mro__[1], method).__doc__


def test_importing_skymule_loads_nothing_heavy() -> None:
    """``import skymule`` (as ``skymule --help`` does) loads the engine only when asked."""
    code = "import sys, skymule; print(sorted(m for m in sys.modules if m.startswith('skymule')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "['skymule']"


def test_a_single_run_through_the_public_api() -> None:
    from skymule.policies import Greedy

    scenario = skymule.load_scenario("paper-sim-fixed")
    result = skymule.simulate(scenario, "greedy")
    log = skymule.run_mission(skymule.build_mission(scenario), Greedy())
    assert float(log.downloaded_bit.sum()) / 1e6 == pytest.approx(
        result.summary["total_downloaded_mbit"], rel=1e-12
    )


def test_a_batch_s_stacked_context_fields_are_each_mission_s() -> None:
    """``stacked(contexts, field)`` (the engine's own arrays, no context made per mission)
    equals the field of every mission's own context, for missions on different tracks."""
    from dataclasses import replace

    import numpy as np

    from skymule.policies.base import stacked
    from skymule.sim.fixed import FixedEngine

    fixed = skymule.build_mission(skymule.load_scenario("paper-sim-fixed"))
    other = skymule.build_mission(skymule.load_scenario("paper-sim-fixed", ["mission.slot_s=2"]))
    missions = [fixed, replace(fixed, buffers_bit=fixed.buffers_bit * 0.5), other]
    contexts = FixedEngine(missions).contexts()
    for field in ("slot_s", "n_slots", "peak_rate_bps", "buffers_bit"):
        each = np.array([getattr(context, field) for context in contexts])
        np.testing.assert_array_equal(stacked(contexts, field), each)
        assert not stacked(contexts, field).flags.writeable
    assert stacked(list(contexts), "slot_s").tolist() == [1.0, 1.0, 2.0]  # any sequence
