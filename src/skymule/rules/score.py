"""The AADM score in force, as the challenge controller computes it, vectorised over missions
(the rule, once: the engines' summaries, their compiled reductions, the environments' reward and
the AADM controller use it; ``skymule.aadm`` adds the challenge's files and bytes).

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

import numpy as np

from skymule.rules.contract import window_slots
from skymule.rules.defaults import AADM_WINDOW_S

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
