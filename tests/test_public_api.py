"""``skymule``'s public API: what a user imports, from one place, loaded when first used."""

from __future__ import annotations

import subprocess
import sys

import pytest

import skymule


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
