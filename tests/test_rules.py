"""The rules layer (``skymule.rules``): each rule once, and what uses another rule says so."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

import skymule
from skymule.rules import contract, home
from skymule.rules.defaults import AADM_WINDOW_S, MAX_HOVER_S

SRC = Path(skymule.__file__).parent

#: Literals that belong to the rules layer only: a window's epsilon and HGAD's hover default.
STRAY = {
    "a window epsilon (use rules.contract.window_slots)": re.compile(
        r"window[^\n]*1e-9|1e-9[^\n]*window", re.IGNORECASE
    ),
    "a hover default (use rules.defaults.MAX_HOVER_S)": re.compile(
        r"hover[^\n]*(=|:)\s*60(\.0)?\b|HOVER_S\s*=\s*60", re.IGNORECASE
    ),
}


def test_no_rule_literal_outside_the_rules_layer() -> None:
    found = []
    for path in sorted(SRC.rglob("*.py")):
        if path.parent.name == "rules":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            found += [
                f"{path.relative_to(SRC)}:{number}: {what}: {line.strip()}"
                for what, pattern in STRAY.items()
                if pattern.search(line)
            ]
    assert not found, "\n".join(found)


def test_the_grep_catches_the_forms_it_is_for() -> None:
    """The patterns above match the lines they replaced (so the test above can fail)."""
    window, hover = STRAY.values()
    assert window.search("    window = tables.aadm_window_s[b] - 1e-9")
    assert window.search("elif self.served_polls * self.poll_s >= self.window_s - 1e-9:")
    assert hover.search("    max_hover_s: float = 60.0,")
    assert hover.search("HGAD_HOVER_S = 60.0")
    assert not hover.search("    max_hover_s: float = MAX_HOVER_S,")


def test_the_rules_layer_imports_nothing_above_it() -> None:
    for path in (SRC / "rules").glob("*.py"):
        for line in path.read_text().splitlines():
            if line.startswith(("import skymule", "from skymule")):
                assert line.startswith("from skymule.rules"), f"{path.name}: {line}"


def test_defaults_are_the_policies_and_scenarios() -> None:
    from skymule.policies import HGAD
    from skymule.policies.registry import HGADParams
    from skymule.scenario import load_scenario

    assert HGADParams().max_hover_s == HGAD().max_hover_s == MAX_HOVER_S == 60.0
    assert load_scenario("aadm-default").mission.aadm_window_s in (None, AADM_WINDOW_S)


def test_window_slots_count_the_slots_starting_inside() -> None:
    # 500 s of 1-s slots: slots 0..499; a window a hair past a slot start takes that slot
    assert contract.window_slots(500.0, 1.0) == 500
    assert contract.window_slots(500.0 + 1e-6, 1.0) == 501
    assert contract.window_slots(0.3 * 3, 0.3) == 3  # 0.8999999...: round-off, not a slot more
    assert contract.window_slots(10.0, 4.0) == 3


def test_rate_choice_differs_from_hgad_on_ties() -> None:
    """The planner's choice breaks rate ties by index; HGAD's by SNR."""
    rate = np.array([[2e6], [2e6], [1e6]])
    snr = np.array([[10.0], [12.0], [30.0]])
    has = contract.servable(rate, np.ones((3, 1)))
    assert int(contract.rate_choice(rate, has)[0]) == 0
    assert int(contract.hgad_choice(rate, snr, has)[0]) == 1
    # off ties they agree, and neither serves a sensor without data
    rate[1, 0] = 3e6
    assert int(contract.rate_choice(rate, has)[0]) == int(contract.hgad_choice(rate, snr, has)[0])
    assert int(contract.rate_choice(rate, np.zeros((3, 1), bool))[0]) == contract.NO_SENSOR


def test_home_budget_is_the_calm_wind_and_bound_forms() -> None:
    """One deadline: metres at the speed cap, seconds under a wind, the bound's reach radius."""
    n_slots, step_m, slot_s = 10, 5.0, 1.0
    slots = np.arange(n_slots)
    metres = home.home_budget(n_slots, slots, step_m)
    seconds = home.home_budget(n_slots, slots, slot_s)
    np.testing.assert_array_equal(metres, seconds * step_m / slot_s)
    assert metres[-1] == 0.0  # after the last slot the UAV must be home
    # the bound's reach radius around home at the start of slot t: (T - t) steps
    np.testing.assert_array_equal(home.home_budget(n_slots, slots - 1, step_m), (10 - slots) * 5.0)
    assert home.time_left_s(n_slots, 4, 0.5) == 3.0


def test_the_aadm_score_by_hand_and_as_rewards() -> None:
    """S = max(0, W - t1) + 100 D_down / D_tot, t1 the end of the completing slot; the
    per-slot rewards of an episode add up to its score."""
    from skymule.rules.score import aadm_scores, slot_rewards

    bits = np.zeros((2, 600))
    bits[0, :470] = 1.0  # 470 bits over slots 0..469: complete at the end of slot 469
    bits[1, 100:600] = 1.0  # 500 bits, but slots 500.. are past the window: 400 count
    total = np.array([470.0, 500.0])
    score = aadm_scores(bits, total, np.array([600, 600]), 1.0, AADM_WINDOW_S)
    np.testing.assert_array_equal(score.t1_s, [470.0, 500.0])
    np.testing.assert_array_equal(score.score, [30.0 + 100.0, 100.0 * 400 / 500])
    counted, completed = np.zeros(2), np.zeros(2, bool)
    window, live, slot_s = np.full(2, AADM_WINDOW_S), np.ones(2, bool), np.ones(2)
    rewards = np.zeros(2)
    for t in range(600):
        ran = np.full(2, t + 1)
        rewards += slot_rewards(bits[:, t], ran, live, slot_s, total, window, counted, completed)
    np.testing.assert_allclose(rewards, score.score, rtol=1e-12)
