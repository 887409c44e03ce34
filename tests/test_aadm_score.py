"""The AADM score in force, pinned on hand-worked cases."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli
from skymule.aadm.score import (
    aadm_score_one,
    aadm_scores,
    poll_download_bit,
    poll_times_s,
    predicted_testbed_score,
    scenario_prediction,
)

MBIT = 1e6


def test_complete_at_320_s() -> None:
    # 1 Mbit a slot, 320 Mbit buffered: the last bit arrives in slot 319, i.e. t1 = 320 s
    parts = aadm_score_one(np.full(320, MBIT), 320 * MBIT, slot_s=1.0)
    assert parts["aadm_complete"] is True
    assert parts["aadm_t1_s"] == 320.0
    assert parts["aadm_s1"] == 180.0  # 500 - 320
    assert parts["aadm_s2"] == 100.0
    assert parts["aadm_score"] == 280.0


def test_incomplete_closes_at_the_window() -> None:
    # 600 slots of 1 Mbit against 1000 Mbit: only the 500 slots inside the window count
    parts = aadm_score_one(np.full(600, MBIT), 1000 * MBIT, slot_s=1.0)
    assert parts["aadm_complete"] is False
    assert parts["aadm_t1_s"] == 500.0
    assert parts["aadm_s1"] == 0.0
    assert parts["aadm_s2"] == pytest.approx(50.0)
    assert parts["aadm_score"] == pytest.approx(50.0)


def test_incomplete_mission_that_ends_before_the_window() -> None:
    parts = aadm_score_one(np.full(200, MBIT), 1000 * MBIT, slot_s=1.0)
    assert parts["aadm_t1_s"] == 200.0
    assert parts["aadm_score"] == pytest.approx(20.0)


def test_a_tower_is_clipped_at_its_volume() -> None:
    # SNR 25 dB -> 5.55 b/s/Hz x 1.4 MHz = 7.77 Mbit offered; the tower has 3 Mbit left
    got = poll_download_bit(np.array([25.0, 25.0]), np.array([3 * MBIT, 100 * MBIT]))
    assert got[0] == pytest.approx(3 * MBIT)
    assert got[1] == pytest.approx(7.77 * MBIT)
    # finishing on a clipped poll completes the mission in that slot
    parts = aadm_score_one(np.array([7.77, 7.77, 3.0]) * MBIT, 18.54 * MBIT, slot_s=1.0)
    assert parts["aadm_complete"] is True
    assert parts["aadm_t1_s"] == 3.0
    assert parts["aadm_score"] == pytest.approx(597.0)


def test_unreadable_snr_counts_as_0_db_and_unheard_as_nothing() -> None:
    # 0 dB is between -2.3 dB (0.38) and 0.2 dB (0.60): 0.38 x 1.4 MHz = 0.532 Mbit a poll
    got = poll_download_bit(np.array([np.nan, -99.0]), np.array([10 * MBIT, 10 * MBIT]))
    assert got[0] == pytest.approx(0.532 * MBIT)
    assert got[1] == 0.0


def test_no_data_counts_before_the_volumes_are_shared() -> None:
    # shared in slot 10 (first poll above 24 m): slots 0..9 do not count, t1 starts at 10
    parts = aadm_score_one(np.full(30, MBIT), 15 * MBIT, slot_s=1.0, share_slot=10)
    assert parts["aadm_t1_s"] == 15.0
    assert parts["aadm_complete"] is True
    assert parts["aadm_score"] == 485.0 + 100.0


def test_vectorised_over_padded_missions_agrees_with_one_at_a_time() -> None:
    rng = np.random.default_rng(3)
    lengths = np.array([50, 120, 80])
    down = np.zeros((3, 120))
    for row, length in enumerate(lengths):
        down[row, :length] = rng.uniform(0, 2, length) * MBIT
    totals = np.array([40.0, 500.0, 60.0]) * MBIT
    shares = np.array([0, 5, 3])
    batch = aadm_scores(down, totals, lengths, 1.0, 100.0, shares)
    for row in range(3):
        one = aadm_score_one(down[row, : lengths[row]], totals[row], 1.0, 100.0, shares[row])
        assert batch.score[row] == pytest.approx(one["aadm_score"])
        assert batch.t1_s[row] == one["aadm_t1_s"]
    assert batch.downloaded_bit[1] < totals[1]  # the window of 100 s cut mission 1 short


def test_nothing_to_download_is_complete_at_zero() -> None:
    parts = aadm_score_one(np.zeros(5), 0.0, slot_s=1.0)
    assert parts["aadm_complete"] is True
    assert parts["aadm_score"] == 600.0


# --- the testbed's clock ------------------------------------------------------------------------


def test_prediction_at_one_second_a_poll_is_the_nominal_rule() -> None:
    for bits, total in ((np.full(320, MBIT), 320 * MBIT), (np.full(600, MBIT), 1000 * MBIT)):
        nominal = aadm_score_one(bits, total, slot_s=1.0)
        predicted = predicted_testbed_score(bits, total, interval_s=1.0)
        assert predicted["aadm_complete"] == nominal["aadm_complete"]
        assert predicted["aadm_t1_s"] == nominal["aadm_t1_s"]
    # complete: the same score; incomplete: the testbed also credits the poll at exactly 500 s
    assert predicted_testbed_score(np.full(320, MBIT), 320 * MBIT, 1.0)["aadm_score"] == 280.0
    assert predicted_testbed_score(np.full(600, MBIT), 1000 * MBIT, 1.0)["aadm_s2"] == 50.1


def test_prediction_at_the_recorded_cadence() -> None:
    # completing at poll 470 (t1 = 470 s nominally) is t1 = 470 x 1.031 = 484.57 s there
    parts = predicted_testbed_score(np.full(470, MBIT), 470 * MBIT)
    assert parts["aadm_poll_interval_s"] == 1.031
    assert parts["aadm_t1_s"] == pytest.approx(484.57)
    assert parts["aadm_score"] == pytest.approx(100 + 500 - 484.57)
    # an unfinished mission: only the polls up to 500 s count (floor(500 / 1.031) + 1 = 485)
    short = predicted_testbed_score(np.full(600, MBIT), 1000 * MBIT)
    assert short["aadm_complete"] is False and short["aadm_s2"] == pytest.approx(48.5)


def test_jitter_is_seeded_and_never_under_the_controllers_second() -> None:
    first = poll_times_s(1000, 1.031, 0.3, seed=7)
    assert np.array_equal(first, poll_times_s(1000, 1.031, 0.3, seed=7))
    assert not np.array_equal(first, poll_times_s(1000, 1.031, 0.3, seed=8))
    assert np.diff(first).min() >= 1.0
    assert first[0] == 0.0 and first.size == 1001


def test_scenario_aadm_section_sets_the_cadence(tmp_path: Path) -> None:
    from skymule.scenario import load_scenario

    base = load_scenario("paper-sim-autonomous")
    assert scenario_prediction(base, np.full(10, MBIT), 10 * MBIT)["aadm_poll_interval_s"] == 1.031
    text = tmp_path / "s.toml"
    text.write_text(
        'name = "x"\n[mission]\nduration_s = 60\n[[sensors]]\nname = "A"\nx_m = 100.0\n'
        "y_m = 0.0\nbuffer_mbit = 10\n[trajectory]\nmode = 'autonomous'\n"
        "[aadm]\npoll_interval_s = 1.5\npoll_jitter_s = 0.2\n"
    )
    spec = load_scenario(str(text))
    parts = scenario_prediction(spec, np.full(10, MBIT), 10 * MBIT)
    assert parts["aadm_poll_interval_s"] == 1.5 and parts["aadm_poll_jitter_s"] == 0.2
    assert parts["aadm_t1_s"] >= 15.0
    done = run_cli("run", str(text))
    assert done.returncode == 0, done.stderr
    assert re.search(r"testbed \(1\.5±0\.2 s/poll\): t1 \d+\.\d s, AADM \d+\.\d", done.stdout)
    text.write_text(text.read_text().replace("1.5", "0.5"))
    bad = run_cli("run", str(text))
    assert bad.returncode == 2 and "poll_interval_s" in bad.stderr
