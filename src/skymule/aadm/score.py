"""The AADM challenge's accounting around its score: what a poll downloads, when the volumes
are shared, and the score the testbed would give at its real poll cadence. The score itself
(:class:`AadmScore`, :func:`aadm_scores`, ...) is a rule and lives in
:mod:`skymule.rules.score`; it is re-exported here.

Downloads are given per slot, (B, T) padded with zeros past each mission's ``n_slots``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from skymule.aadm.rules import AADM_BANDWIDTH_HZ as AADM_BANDWIDTH_HZ
from skymule.aadm.rules import AADM_POLL_S as AADM_POLL_S
from skymule.aadm.rules import AADM_WINDOW_S as AADM_WINDOW_S
from skymule.aadm.rules import SHARE_ALTITUDE_M as SHARE_ALTITUDE_M
from skymule.aadm.rules import TESTBED_POLL_INTERVAL_S as TESTBED_POLL_INTERVAL_S
from skymule.aadm.rules import UNREADABLE_SNR_DB as UNREADABLE_SNR_DB
from skymule.radio.rates import BUILTIN_RATE_TABLES
from skymule.rules.contract import ROUND_OFF, served_bits
from skymule.rules.score import COMPLETE_RTOL as COMPLETE_RTOL
from skymule.rules.score import AadmScore as AadmScore
from skymule.rules.score import aadm_from_progress as aadm_from_progress
from skymule.rules.score import aadm_score_one as aadm_score_one
from skymule.rules.score import aadm_scores as aadm_scores
from skymule.rules.score import slot_rewards as slot_rewards


def poll_download_bit(
    snr_db: np.ndarray,
    left_bit: np.ndarray,
    poll_s: float = AADM_POLL_S,
    bandwidth_hz: float = AADM_BANDWIDTH_HZ,
) -> np.ndarray:
    """Bits the controller credits a served tower for one poll (any shape, elementwise).

    Efficiency of the served tower's SNR in the AADM CQI table x bandwidth x the nominal poll
    length, clipped to the data the tower has left. NaN means "SNR could not be read" and
    counts as 0 dB (the controller's rule); a tower not heard from reports -99 dB (rate 0).
    """
    snr = np.where(np.isnan(np.asarray(snr_db, float)), UNREADABLE_SNR_DB, snr_db)
    rate_bps = BUILTIN_RATE_TABLES["aadm-lte-cqi"].efficiency(snr) * bandwidth_hz
    return served_bits(rate_bps, np.maximum(np.asarray(left_bit, float), 0.0), poll_s)


def share_slot_from_altitude(altitude_m: np.ndarray) -> int:
    """Slot of the first sample above :data:`SHARE_ALTITUDE_M` (len(altitude_m) if never)."""
    above = np.asarray(altitude_m, float) > SHARE_ALTITUDE_M
    return int(np.argmax(above)) if above.any() else int(above.size)


# --- the testbed's clock -----------------------------------------------------------------------


def poll_times_s(
    n_polls: int, interval_s: float = TESTBED_POLL_INTERVAL_S, jitter_s: float = 0.0, seed: int = 0
) -> np.ndarray:
    """(n_polls + 1,) wall time of each poll since sharing on the testbed [s], and of the poll
    after the last: ``interval_s`` apart, or with gaps drawn ``N(interval_s, jitter_s)``
    (seeded) and never under the controller's 1 s (it answers at most one poll a second)."""
    if jitter_s > 0:
        gaps = np.random.default_rng(seed).normal(interval_s, jitter_s, n_polls)
        gaps = np.maximum(gaps, AADM_POLL_S)
    else:
        gaps = np.full(n_polls, float(interval_s))
    return np.concatenate([[0.0], np.cumsum(gaps)])


def predicted_testbed_score(
    per_poll_bit: np.ndarray,
    total_bit: float,
    interval_s: float = TESTBED_POLL_INTERVAL_S,
    jitter_s: float = 0.0,
    seed: int = 0,
    window_s: float = AADM_WINDOW_S,
) -> dict[str, float | bool]:
    """The score the testbed's controller would give a mission, polled at its real cadence.

    ``per_poll_bit`` (T,) is what each poll since sharing credited (one 1-s slot of
    ``skymule run``, or one poll of a flight on the poll clock; the data per poll is the same
    on the testbed, which credits the nominal 1 s a poll). The testbed measures t1 on the wall
    clock and learns of completion from the next telemetry message; with the telemetry sent
    just before each poll (as ``skymule aadm agent`` does), poll k is at ``t_k``
    (:func:`poll_times_s`), the polls counted are those at or before the window's end, and a
    download completed by poll c has ``t1 = t_(c+1)``. With a 1-s cadence that is the nominal
    rule's t1; at 1.031 s a poll, a mission completing at poll 470 gets t1 = 484.6 s.
    Keys: those of :func:`aadm_score_one` and ``aadm_poll_interval_s``, ``aadm_poll_jitter_s``.
    The UAV's motion is the engine's (one slot a poll): a slower cadence also moves it further
    between polls on the testbed, which this does not model.
    """
    bits = np.asarray(per_poll_bit, float).reshape(-1)
    times = poll_times_s(bits.size, interval_s, jitter_s, seed)
    counted = np.where(times[:-1] <= window_s + ROUND_OFF, bits, 0.0)
    cumulative = np.cumsum(counted)
    threshold = total_bit * (1.0 - COMPLETE_RTOL)
    got = float(cumulative[-1]) if cumulative.size else 0.0
    if total_bit <= 0:
        complete, t1 = True, 0.0
    elif cumulative.size and got >= threshold:
        complete = True
        t1 = float(times[int(np.argmax(cumulative >= threshold)) + 1])
    else:
        complete = False
        t1 = float(min(times[-1], window_s))
    s1 = max(0.0, window_s - t1) if complete else 0.0
    s2 = 100.0 if total_bit <= 0 else 100.0 * min(got, total_bit) / total_bit
    return {
        "aadm_t1_s": t1,
        "aadm_s1": s1,
        "aadm_s2": s2,
        "aadm_complete": complete,
        "aadm_score": s1 + s2,
        "aadm_poll_interval_s": float(interval_s),
        "aadm_poll_jitter_s": float(jitter_s),
    }


def describe_cadence(interval_s: float, jitter_s: float) -> str:
    """``1.031 s a poll`` / ``1.031 s a poll, jitter 0.3 s``: the cadence a prediction assumes."""
    text = f"{interval_s:g} s a poll"
    return text + (f", jitter {jitter_s:g} s" if jitter_s > 0 else "")


def scenario_prediction(
    scenario: Any, per_poll_bit: np.ndarray, total_bit: float, window_s: float = AADM_WINDOW_S
) -> dict[str, float | bool]:
    """:func:`predicted_testbed_score` at the scenario's ``[aadm]`` cadence (default: the recorded
    1.031 s a poll, steady), jitter drawn from the scenario's seed."""
    spec = getattr(scenario, "aadm", None)
    interval = TESTBED_POLL_INTERVAL_S if spec is None else float(spec.poll_interval_s)
    jitter = 0.0 if spec is None else float(spec.poll_jitter_s)
    seed = int(getattr(scenario, "seed", 0))
    return predicted_testbed_score(per_poll_bit, total_bit, interval, jitter, seed, window_s)
