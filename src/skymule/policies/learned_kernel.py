"""The ``learned`` scorer's compiled twin: :func:`option_features` and :func:`scores` of one
model as loops that numba compiles (``fast`` extra), for one decision at a time.

numpy pays a few microseconds per array operation, and a decision of one mission is a few
hundred small operations; compiled, the same arithmetic takes microseconds. Most of those are
the hidden layer's tanh (32 per option): :func:`tanh` computes it from one ``exp``, which is
about twice as fast as the C library's ``tanh`` and within 2.3e-16 of it. Without numba the
numpy form runs (:func:`skymule.policies.learned.scores`). ``tests/test_learned_policy.py``
holds the two equal (to round-off: numpy's matrix products sum in another order) and runs this
one as plain Python where numba is absent.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache

import numpy as np

from skymule.policies.options import FRACTIONS as OPTION_FRACTIONS
from skymule.rules.contract import ROUND_OFF, served_bits
from skymule.rules.defaults import MAX_HOVER_S
from skymule.sim import compiled

#: :data:`skymule.policies.options.FRACTIONS` as an array (numba reads module globals).
FRACTIONS = np.array(OPTION_FRACTIONS)


def score_rows(
    travel: np.ndarray,
    back: np.ndarray,
    pair: np.ndarray,
    home: np.ndarray,
    slots_left: np.ndarray,
    n_slots: np.ndarray,
    slot_s: np.ndarray,
    remaining: np.ndarray,
    initial: np.ndarray,
    peak: np.ndarray,
    rate_now: np.ndarray,
    usable: np.ndarray,
    visited: np.ndarray,
    near: np.ndarray,
    fractions: np.ndarray,
    encoder_w: np.ndarray,
    encoder_b: np.ndarray,
    hidden_w: np.ndarray,
    hidden_b: np.ndarray,
    out_w: np.ndarray,
    out_b: float,
    linear_w: np.ndarray,
    home_w: np.ndarray,
    home_b: float,
    out: np.ndarray,
) -> None:
    """Scores (R, N*D + 1) of R decisions into ``out`` (-inf where not allowed); the
    arguments are the :class:`~skymule.policies.options.Decision` fields and model 0's
    weights (see :func:`skymule.policies.learned.scores`)."""
    rows, n = travel.shape
    n_frac = fractions.shape[0]
    width = n_frac + 1
    hidden = encoder_b.shape[0]
    n_hidden = hidden_b.shape[0]
    n_sensor, n_mission = 12, 4
    n_option = 8
    sensor = np.zeros((n, n_sensor))
    option = np.zeros((n, width, n_option))
    stay = np.zeros((n, width))
    allowed = np.zeros((n, width), np.bool_)
    encoded = np.zeros((n, hidden))
    mission = np.zeros(n_mission)
    x = np.zeros(n_sensor + n_option + n_mission + 2 * hidden)
    base = np.empty(n_hidden)
    per_sensor = np.empty(n_hidden)
    acts = np.empty(n_hidden)
    for r in range(rows):
        left = slots_left[r]
        dt = slot_s[r]
        peak_max = 0.0
        data_max = 0.0
        travel_min = math.inf
        data_top = -math.inf
        total = 0.0
        count_usable = 0
        for k in range(n):
            if usable[r, k]:
                peak_max = max(peak_max, peak[r, k])
                data_max = max(data_max, remaining[r, k])
                travel_min = min(travel_min, travel[r, k])
                data_top = max(data_top, remaining[r, k])
                total += remaining[r, k]
                count_usable += 1
        if peak_max <= 0:
            peak_max = 1.0
        if data_max <= 0:
            data_max = 1.0
        best = peak_max * dt
        # HGAD's next target: most data among usable sensors not visited (all once each was)
        any_pending = False
        for k in range(n):
            if usable[r, k] and not visited[r, k]:
                any_pending = True
        target = -1
        target_data = -math.inf
        for k in range(n):
            pending = usable[r, k] and (not visited[r, k] or not any_pending)
            if pending and remaining[r, k] > target_data:
                target, target_data = k, remaining[r, k]
        hgad_slots = math.ceil(MAX_HOVER_S / dt - ROUND_OFF)
        for k in range(n):
            need = 0.0
            if peak[r, k] > 0:
                need = math.ceil(remaining[r, k] / (peak[r, k] * dt) - ROUND_OFF)
            onward = math.inf
            spread = 0.0
            others = 0
            for j in range(n):
                if usable[r, j] and j != k:
                    onward = min(onward, pair[r, k, j])
                    spread += pair[r, k, j]
                    others += 1
            if onward == math.inf:
                onward = 0.0
            spread = spread / max(others, 1)
            ok = usable[r, k]
            safe_peak = peak[r, k] if peak[r, k] > 0 else 1.0
            safe_initial = initial[r, k] if initial[r, k] > 0 else 1.0
            values = (
                travel[r, k] / left,
                back[r, k] / left,
                onward / left,
                spread / left,
                min(need / left, 4.0),
                peak[r, k] / peak_max,
                remaining[r, k] / data_max,
                remaining[r, k] / safe_initial,
                min(rate_now[r, k] / safe_peak, 2.0),
                1.0 if ok and travel[r, k] == travel_min else 0.0,
                1.0 if ok and remaining[r, k] == data_top else 0.0,
                1.0 if visited[r, k] else 0.0,
            )
            for f in range(n_sensor):
                sensor[k, f] = values[f] if ok else 0.0
            spare = left - travel[r, k] - back[r, k]
            cap = max(min(need, spare), 0.0)
            for j in range(n_frac):
                stay[k, j] = max(math.ceil(fractions[j] * cap - ROUND_OFF), 0.0)
            stay[k, n_frac] = max(min(cap, hgad_slots), 0.0)
            full = max(stay[k, n_frac - 1], 1.0)
            for j in range(width):
                s = stay[k, j]
                hovers = j == n_frac or fractions[j] > 0
                allowed[k, j] = ok and ((s >= 1) if hovers else not near[r, k])
                bits = served_bits(peak[r, k] * s, remaining[r, k], dt)
                fraction = fractions[j] if j < n_frac else s / full
                after = left - travel[r, k] - s - (onward + back[r, k])
                rest = min(total - bits, best * max(after, 0.0))
                feats = (
                    s / left,
                    fraction,
                    bits / (best * left),
                    bits / (best * max(travel[r, k] + s, 1.0)),
                    (left - travel[r, k] - s - back[r, k]) / left,
                    1.0 if fraction == 0 else 0.0,
                    1.0 if (j == n_frac and k == target and any_pending_or_usable(count_usable))
                    else 0.0,
                    (bits + rest) / (best * left),
                )  # fmt: skip
                for f in range(n_option):
                    option[k, j, f] = feats[f] if ok else 0.0
        mission[0] = left / n_slots[r]
        mission[1] = home[r] / left
        mission[2] = count_usable / n
        mission[3] = total / (peak_max * dt * left)
        # encoder and pooling over sensors with an allowed option
        count = 0
        for h in range(hidden):
            x[n_sensor + n_option + n_mission + h] = 0.0
            x[n_sensor + n_option + n_mission + hidden + h] = -1.0
        for k in range(n):
            live = False
            for j in range(width):
                live = live or allowed[k, j]
            for h in range(hidden):
                acc = encoder_b[h]
                for f in range(n_sensor):
                    acc += sensor[k, f] * encoder_w[f, h]
                for f in range(n_mission):
                    acc += mission[f] * encoder_w[n_sensor + f, h]
                encoded[k, h] = tanh(acc)
            if live:
                count += 1
                for h in range(hidden):
                    x[n_sensor + n_option + n_mission + h] += encoded[k, h]
                    top = n_sensor + n_option + n_mission + hidden + h
                    x[top] = max(x[top], encoded[k, h])
        for h in range(hidden):
            x[n_sensor + n_option + n_mission + h] /= max(count, 1)
            if count == 0:
                x[n_sensor + n_option + n_mission + hidden + h] = 0.0
        for f in range(n_mission):
            x[n_sensor + n_option + f] = mission[f]
        value_home = home_b
        for f in range(n_mission):
            value_home += mission[f] * home_w[f]
        for h in range(2 * hidden):
            value_home += x[n_sensor + n_option + n_mission + h] * home_w[n_mission + h]
        out[r, n * width] = value_home
        # the hidden layer's inputs are [sensor | option | mission | pooled]: the mission's and
        # the pool's part is the same for every option of this decision and the sensor's for
        # every duration, so each is summed once (the order differs from numpy's product by
        # round-off only)
        shared = n_sensor + n_option
        base_linear = out_b
        for f in range(shared, shared + n_mission):
            base_linear += x[f] * linear_w[f]
        for u in range(n_hidden):
            base[u] = hidden_b[u]
        for f in range(shared, x.shape[0]):
            xf = x[f]
            for u in range(n_hidden):
                base[u] += xf * hidden_w[f, u]
        for k in range(n):
            sensor_linear = base_linear
            for u in range(n_hidden):
                per_sensor[u] = base[u]
            for f in range(n_sensor):
                xf = sensor[k, f]
                sensor_linear += xf * linear_w[f]
                for u in range(n_hidden):
                    per_sensor[u] += xf * hidden_w[f, u]
            for j in range(width):
                if not allowed[k, j]:
                    out[r, k * width + j] = -math.inf
                    continue
                value = sensor_linear
                for u in range(n_hidden):
                    acts[u] = per_sensor[u]
                for f in range(n_option):
                    xf = option[k, j, f]
                    value += xf * linear_w[n_sensor + f]
                    for u in range(n_hidden):
                        acts[u] += xf * hidden_w[n_sensor + f, u]
                for u in range(n_hidden):
                    value += tanh(acts[u]) * out_w[u]
                out[r, k * width + j] = value


def tanh(a: float) -> float:
    """tanh(a) as 1 - 2 / (exp(2|a|) + 1) with a's sign: one ``exp`` (cheaper than libm's
    ``tanh``, which the scorer calls ~30 times per option), within 2.3e-16 of ``math.tanh``
    in absolute terms (tested from 1e-300 to 1e300 of either sign); +-1 for +-inf, NaN for
    NaN. |a| is capped at 20, past which tanh rounds to +-1 (and exp would overflow)."""
    y = math.exp(2.0 * min(abs(a), 20.0))
    return math.copysign(1.0 - 2.0 / (y + 1.0), a)


def any_pending_or_usable(count_usable: int) -> bool:
    """HGAD has a next target when any sensor is usable."""
    return count_usable > 0


@cache
def score_kernel() -> Callable[..., None]:
    """:func:`score_rows`, compiled by numba when it is installed (else plain Python)."""
    if not compiled.available():
        return score_rows
    return compiled.jit(
        score_rows,
        (any_pending_or_usable, served_bits, tanh),
        (any_pending_or_usable, tanh),
    )
