"""The AADM score in force, as the challenge controller computes it, vectorised over missions.

Rules (issue "AADM for real", ``shared/data/README.md``):

* downloads count from the slot in which the volumes were shared with the UAV (the first
  poll above 24 m on a flight; slot 0 in a simulation), and the timer t1 starts there;
* the controller stops serving when the window closes: slot k (0-based since sharing) is
  served while its start ``k * slot_s`` is before ``window_s`` (a 500-s simulation with 1-s
  slots is 500 served slots);
* t1 is the end of the slot in which the last bit arrived, since sharing, when everything
  was downloaded; otherwise the time the window closed or the mission ended, whichever came
  first;
* ``S = max(0, (window_s - t1) * complete) + 100 * D_down / D_tot``; there is no landing
  term (the testbed checks landing separately).

Downloads are given per slot, (B, T) padded with zeros past each mission's ``n_slots``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from skymule.aadm.rules import AADM_BANDWIDTH_HZ as AADM_BANDWIDTH_HZ
from skymule.aadm.rules import AADM_POLL_S as AADM_POLL_S
from skymule.aadm.rules import AADM_WINDOW_S as AADM_WINDOW_S
from skymule.aadm.rules import SHARE_ALTITUDE_M as SHARE_ALTITUDE_M
from skymule.aadm.rules import TESTBED_POLL_INTERVAL_S as TESTBED_POLL_INTERVAL_S
from skymule.aadm.rules import UNREADABLE_SNR_DB as UNREADABLE_SNR_DB
from skymule.radio.rates import BUILTIN_RATE_TABLES
from skymule.sim.contract import served_bits, window_slots

#: Relative tolerance under which a buffer counts as emptied (float round-off of Mbit sums).
COMPLETE_RTOL = 1e-9


@dataclass(frozen=True)
class AadmScore:
    """Per-mission parts of the AADM score, each (B,).

    Attributes:
        t1_s: completion time since sharing, or when the window closed / the mission ended.
        s1: completion bonus, max(0, window_s - t1) if everything was downloaded, else 0.
        s2: 100 * downloaded / total (100 when there was nothing to download).
        complete: whether every buffered bit was downloaded within the window.
        downloaded_bit: bits that counted (after sharing, inside the window).
        score: s1 + s2.
    """

    t1_s: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    complete: np.ndarray
    downloaded_bit: np.ndarray
    score: np.ndarray


def aadm_scores(
    downloaded_bit: np.ndarray,
    total_bit: np.ndarray,
    n_slots: np.ndarray,
    slot_s: float | np.ndarray,
    window_s: float | np.ndarray = AADM_WINDOW_S,
    share_slot: np.ndarray | None = None,
) -> AadmScore:
    """The AADM score of B missions.

    Args:
        downloaded_bit: (B, T) bits downloaded in each slot (any tower), zero-padded.
        total_bit: (B,) total buffered bits D_tot.
        n_slots: (B,) slots each mission ran (slots at or past it are ignored).
        slot_s: slot length [s] (the controller's nominal 1 s per poll); scalar or (B,).
        window_s: download window since sharing [s]; scalar or (B,).
        share_slot: (B,) slot in which the volumes were shared (default 0).
    """
    # C order: row sums then take numpy's pairwise order whatever the caller's layout, so one
    # mission scores bit for bit the same alone or inside a batch
    down = np.ascontiguousarray(np.atleast_2d(np.asarray(downloaded_bit, float)))
    if down.shape[1] == 0:  # missions that ran no slot: one empty slot keeps argmax defined
        down = np.zeros((down.shape[0], 1))
    n_missions, width = down.shape
    total = np.asarray(total_bit, float).reshape(n_missions)
    ran = np.asarray(n_slots, int).reshape(n_missions)
    share = (
        np.zeros(n_missions, int)
        if share_slot is None
        else np.asarray(share_slot, int).reshape(n_missions)
    )
    slot = np.broadcast_to(np.asarray(slot_s, float), (n_missions,))
    window = np.broadcast_to(np.asarray(window_s, float), (n_missions,))
    slots = np.arange(width)[None, :]
    inside = window_slots(window, slot)
    if share.any() or (inside < width).any():
        since = slots - share[:, None]  # slot index since sharing
        counted = (since >= 0) & (slots < ran[:, None]) & (since < inside[:, None])
        got = np.where(counted, down, 0.0)
    else:  # every slot counts (shared at once, window past the end; padding holds zeros)
        counted, got = None, down
    cumulative = np.cumsum(got, axis=1)
    threshold = total * (1.0 - COMPLETE_RTOL)
    nothing = total <= 0
    first = np.zeros(n_missions, np.int64)
    done = ~nothing & (cumulative[:, -1] >= threshold)
    if done.any():  # the slot each completing mission reached its total in
        rows = np.flatnonzero(done)
        reached = cumulative[rows] >= threshold[rows, None]
        if counted is not None:
            reached &= counted[rows]
        done[rows] = reached.any(axis=1)
        first[rows] = reached.argmax(axis=1)
    # the running sum (not a pairwise row sum): trailing padding adds exact zeros, so a mission
    # scores bit for bit the same alone or inside a padded batch
    first_since_share = np.where(done, first - share, -1)
    served_s = np.maximum(ran - share, 0) * slot
    return aadm_from_progress(total, served_s, slot, window, cumulative[:, -1], first_since_share)


def aadm_from_progress(
    total_bit: np.ndarray,
    served_s: np.ndarray,
    slot_s: np.ndarray,
    window_s: np.ndarray,
    counted_bit: np.ndarray,
    first: np.ndarray,
) -> AadmScore:
    """The AADM score of B missions from how far each got (the rule, once for every engine).

    Args:
        total_bit: (B,) total buffered bits D_tot.
        served_s: (B,) time from sharing the volumes to the end of the mission [s].
        slot_s: (B,) slot length [s].
        window_s: (B,) download window [s].
        counted_bit: (B,) bits downloaded inside the window.
        first: (B,) slot since sharing in which the counted downloads reached the total
            (within ``COMPLETE_RTOL``), -1 if they never did.
    """
    threshold = total_bit * (1.0 - COMPLETE_RTOL)
    nothing = total_bit <= 0
    done = ~nothing & (counted_bit >= threshold) & (first >= 0)
    complete = done | nothing
    t1 = np.where(
        nothing,
        0.0,
        np.where(complete, (np.where(done, first, 0) + 1) * slot_s, np.minimum(window_s, served_s)),
    )
    downloaded = np.minimum(counted_bit, total_bit)
    s1 = np.where(complete, np.maximum(0.0, window_s - t1), 0.0)
    s2 = np.where(nothing, 100.0, 100.0 * downloaded / np.where(nothing, 1.0, total_bit))
    return AadmScore(
        t1_s=t1.astype(float),
        s1=s1,
        s2=s2,
        complete=complete,
        downloaded_bit=downloaded,
        score=s1 + s2,
    )


def aadm_score_one(
    downloaded_bit: np.ndarray,
    total_bit: float,
    slot_s: float,
    window_s: float = AADM_WINDOW_S,
    share_slot: int = 0,
) -> dict[str, float | bool]:
    """One mission's score parts as plain values (``aadm_t1_s``, ``aadm_s1`` ...).

    ``downloaded_bit`` is (T,) bits per slot; the mission ran T slots.
    """
    per_slot = np.asarray(downloaded_bit, float).reshape(1, -1)
    parts = aadm_scores(
        per_slot,
        np.array([total_bit]),
        np.array([per_slot.shape[1]]),
        slot_s,
        window_s,
        np.array([share_slot]),
    )
    return {
        "aadm_t1_s": float(parts.t1_s[0]),
        "aadm_s1": float(parts.s1[0]),
        "aadm_s2": float(parts.s2[0]),
        "aadm_complete": bool(parts.complete[0]),
        "aadm_score": float(parts.score[0]),
    }


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


def slot_rewards(
    bits: np.ndarray,
    slots_run: np.ndarray,
    live: np.ndarray,
    slot_s: np.ndarray,
    total_bit: np.ndarray,
    window_s: np.ndarray,
    counted_bit: np.ndarray,
    completed: np.ndarray,
) -> np.ndarray:
    """(B,) the AADM score in force spread over B episodes, one slot each: summed over an
    episode, the rewards are its :func:`aadm_scores` score.

    A slot inside the download window earns 100 x bits / total; the slot that completes the
    download also earns max(0, window - t1) (t1 the end of that slot); a mission with nothing
    to download earns 100 + window in its first slot.

    Args:
        bits: (B,) bits downloaded this slot.
        slots_run: (B,) slots each episode has run, this one included.
        live: (B,) False for episodes that did not step (their reward is 0).
        slot_s: (B,) slot length [s].
        total_bit: (B,) total buffered bits.
        window_s: (B,) download window [s].
        counted_bit: (B,) bits counted so far; updated in place.
        completed: (B,) whether the download completed already; updated in place.
    """
    counted = live & (slots_run - 1 < window_slots(window_s, slot_s))
    got = np.where(counted, bits, 0.0)
    counted_bit += got
    has = total_bit > 0
    reward = np.where(has, 100.0 * got / np.where(has, total_bit, 1.0), 0.0)
    first = live & (slots_run == 1) & ~has  # nothing to download: complete at once
    reward = np.where(first, 100.0 + window_s, reward)
    emptied = counted & ~completed & has & (counted_bit >= total_bit * (1.0 - COMPLETE_RTOL))
    completed |= emptied
    bonus = np.maximum(0.0, window_s - slots_run * slot_s)
    return reward + np.where(emptied, bonus, 0.0)


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
    counted = np.where(times[:-1] <= window_s + 1e-9, bits, 0.0)
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
