"""The fixed-path bound's LPs, solved two ways: every column, or column generation.

The prefix LP ``V(L)`` (see :mod:`skymule.bounds.fixed` for why it matters) has one
time-shared slot of ``dt`` at each sample ``k = 0..L``, ``H = (T - L - 1) dt`` of hover time
and one buffer row per sensor::

    max  sum_{k,i} R[k,i] s[k,i] + sum_i P[i] h[i]
    s.t. sum_i s[k,i] <= dt  (k <= L),   sum_i h[i] <= H,
         sum_k R[k,i] s[k,i] + P[i] h[i] <= Q[i],   s, h >= 0,

with ``P[i] = max_{k<=L} R[k,i]``. Pricing the buffers at ``lam >= 0`` (Lagrangian duality)
gives, for every ``L`` at once, the bound computed by :func:`dual_bounds`::

    V(L) <= Phi_L(lam) = lam.Q + dt sum_{k<=L} g_k + H max_{k<=L} g_k,
    g_k = max(0, max_i R[k,i] (1 - lam_i)),

with equality at the LP's optimal buffer duals (LP strong duality).

:func:`prefix_lp` is the plain reference: all ``(L + 1) N`` serve columns, one HiGHS solve.

:func:`prefix_lp_columns` is the fast path, *column generation*
(:func:`time_sharing_columns`, which also solves the paper's no-hover LP: slot capacities
``c_k dt`` and no hover time): at the optimum slot ``k`` serves only sensors whose priced
gain ``R[k,i] (1 - lam_i)`` is the slot's largest, so it solves the LP over the few columns
whose priced gain is within :data:`NEAR_BEST` of the slot's best under a guess of the prices
(the search passes the prices that gave this ``L`` its current dual bound), takes
that LP's buffer duals ``lam`` and checks them on the *whole* LP: ``Phi_L(lam)`` is an upper
bound on ``V(L)`` and the restricted optimum ``v`` a lower bound, so ``Phi_L(lam) <= v`` (to
:data:`COLUMN_TOL` relative) proves ``v = V(L)``. Otherwise the columns near the best under the
new prices join and it solves again. Every slot's best column is always in the restricted LP, so
once a round adds nothing the restricted duals are feasible for the whole LP and the check holds
(up to HiGHS's own tolerances; the loop then stops too). The reported value is
``max(v, Phi_L(lam))``, never below the certified bound ``Phi_L(lam) >= V(L)``. At 3,600 slots x
16 sensors the restricted LP has about 3,000 columns instead of up to 57,600 and about two
rounds suffice, so a prefix LP takes ~10-40 ms of CPU instead of 0.2-3.6 s (docs/bounds.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

__all__ = [
    "PrefixSolution",
    "dual_bounds",
    "lagrangian_bound",
    "prefix_lp",
    "prefix_lp_columns",
    "time_sharing_columns",
]

#: A column joins the restricted LP when its priced gain is at least this share of the best
#: priced gain in its slot (within 3 %). Smaller means bigger LPs and fewer rounds: on the
#: 16-sensor case of benchmarks/bench_bound.py (dual simplex) 0.6 took 14 s of CPU (LPs nearly
#: as big as the full one), 0.8 2.5 s, 0.9 1.4 s, 0.97-1.0 0.8-1.0 s.
NEAR_BEST = 0.97

#: Relative gap ``(Phi_L(lam) - v) / max(1, v)`` at which column generation stops.
COLUMN_TOL = 1e-9


@dataclass(frozen=True)
class PrefixSolution:
    """Optimum of the prefix LP for one last sample ``L``.

    ``bits`` is ``V(L)`` (bit); ``lam`` the ``(N,)`` buffer prices; ``transit_s`` the
    ``(L + 1, N)`` serve time in the mandatory slots and ``hover_s`` the ``(N,)`` hover time
    serving sensor ``i`` at its best sample (s); ``rounds`` the number of LPs solved.
    """

    bits: float
    lam: np.ndarray
    transit_s: np.ndarray
    hover_s: np.ndarray
    status: str
    rounds: int = 1


def dual_bounds(
    rate: np.ndarray, buf: np.ndarray, slot_s: float, n_slots: int, lam: np.ndarray
) -> np.ndarray:
    """Weak-duality bound ``Phi_L(lam)`` on ``V(L)`` for every last sample ``L`` at once.

    ``rate`` is ``(K, N)`` (bit/s) with ``K <= T``, ``lam`` an ``(N,)`` buffer price >= 0.
    Returns ``(K,)`` bits: ``lam . Q + dt sum_{k<=L} g_k + (T - L - 1) dt max_{k<=L} g_k`` with
    ``g_k = max(0, max_i R[k, i] (1 - lam_i))``.
    """
    gain = np.maximum(0.0, np.max(rate * (1.0 - lam), axis=1))
    hover_s = (n_slots - 1 - np.arange(rate.shape[0])) * slot_s
    return float(lam @ buf) + slot_s * np.cumsum(gain) + hover_s * np.maximum.accumulate(gain)


def prefix_lp(
    rate: np.ndarray, buf: np.ndarray, slot_s: float, n_slots: int, last: int, lp_method: str
) -> PrefixSolution:
    """Reference ``V(L)``: the prefix LP with every serve column, one HiGHS solve.

    ``rate`` is ``(K, N)`` (bit/s), ``last`` is ``L < K``. Hover is collapsed to one column per
    sensor at its best rate over samples ``0..L``.
    """
    pre = rate[: last + 1]
    k, n = pre.shape
    best = pre.max(axis=0)
    a_time = sp.kron(sp.eye_array(k), np.ones((1, n)), format="csr")
    a_buf = sp.csr_array(
        (pre.ravel(), (np.tile(np.arange(n), k), np.arange(k * n))), shape=(n, k * n)
    )
    a = sp.vstack(
        [
            sp.hstack([a_time, sp.csr_array((k, n))]),
            sp.hstack([sp.csr_array((1, k * n)), np.ones((1, n))]),
            sp.hstack([a_buf, sp.diags_array(best)]),
        ],
        format="csr",
    )
    b = np.concatenate([np.full(k, slot_s), [(n_slots - 1 - last) * slot_s], buf])
    res = linprog(
        -np.concatenate([pre.ravel(), best]), A_ub=a, b_ub=b, bounds=(0, None), method=lp_method
    )
    if res.status != 0:
        raise RuntimeError(f"HiGHS failed on the prefix LP (L={last}): {res.message}")
    return PrefixSolution(
        bits=float(-res.fun),
        lam=np.clip(-res.ineqlin.marginals[k + 1 :], 0.0, None),
        transit_s=np.reshape(res.x[: k * n], (k, n)),
        hover_s=res.x[k * n :],
        status=str(res.message),
    )


def lagrangian_bound(
    rate: np.ndarray,
    buf: np.ndarray,
    caps_s: np.ndarray,
    hover_s: float,
    hover_rate: np.ndarray,
    lam: np.ndarray,
) -> float:
    """Weak-duality bound of :func:`time_sharing_columns`'s LP at buffer prices ``lam >= 0``.

    ``lam.Q + sum_k caps_k g_k + H max(0, max_i P_i (1 - lam_i))`` with
    ``g_k = max(0, max_i R[k, i] (1 - lam_i))`` (bit); for the prefix LP it is ``Phi_L(lam)``.
    """
    gain = np.maximum(0.0, np.max(rate * (1.0 - lam), axis=1, initial=0.0))
    hover_gain = max(0.0, float(np.max(hover_rate * (1.0 - lam), initial=0.0)))
    return float(lam @ buf + caps_s @ gain + hover_s * hover_gain)


def _restricted_lp(
    rate: np.ndarray,
    buf: np.ndarray,
    caps_s: np.ndarray,
    hover_s: float,
    hover_rate: np.ndarray,
    chosen: np.ndarray,
    lp_method: str,
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, str]:
    """The time-sharing LP over the serve columns where ``chosen`` (``(K, N)`` bool) is True.

    Every hover column is kept. Returns ``(bits, lam (N,), serve_s (K, N), hover_s (N,),
    status)``.
    """
    k, n = rate.shape
    col_k, col_i = np.nonzero(chosen)
    m = col_k.size
    gain = rate[col_k, col_i]
    sensors = np.arange(n)
    # rows: time of slot 0..K-1, hover time (K), buffer of sensor i (K + 1 + i); serve column j
    # (slot col_k[j], sensor col_i[j]) enters its slot's time row and its sensor's buffer row,
    # hover column m + i the hover row and sensor i's buffer row
    a = sp.csc_array(
        (
            np.concatenate([np.ones(m), gain, np.ones(n), hover_rate]),
            (
                np.concatenate([col_k, k + 1 + col_i, np.full(n, k), k + 1 + sensors]),
                np.concatenate([np.arange(m), np.arange(m), m + sensors, m + sensors]),
            ),
        ),
        shape=(k + 1 + n, m + n),
    )
    b = np.concatenate([caps_s, [hover_s], buf])
    res = linprog(
        -np.concatenate([gain, hover_rate]), A_ub=a, b_ub=b, bounds=(0, None), method=lp_method
    )
    if res.status != 0:
        raise RuntimeError(f"HiGHS failed on a restricted time-sharing LP: {res.message}")
    serve = np.zeros((k, n))
    serve[col_k, col_i] = res.x[:m]
    lam = np.clip(-res.ineqlin.marginals[k + 1 :], 0.0, None)
    return float(-res.fun), lam, serve, res.x[m:], str(res.message)


def _near_best(rate: np.ndarray, caps_s: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """``(K, N)`` bool: positive priced gain within NEAR_BEST of the best in its slot (cap > 0)."""
    priced = rate * (1.0 - lam)
    best = priced.max(axis=1, keepdims=True, initial=0.0)
    return (priced > 0.0) & (priced >= NEAR_BEST * best) & (caps_s[:, None] > 0.0)


def time_sharing_columns(
    rate: np.ndarray,
    buf: np.ndarray,
    caps_s: np.ndarray,
    hover_s: float,
    hover_rate: np.ndarray,
    lam_guess: np.ndarray,
    lp_method: str,
) -> PrefixSolution:
    """Column generation (module docstring) for the general time-sharing LP::

        max  sum R[k,i] s[k,i] + sum_i P[i] h[i]
        s.t. sum_i s[k,i] <= caps[k],  sum_i h[i] <= H,  sum_k R[k,i] s[k,i] + P[i] h[i] <= Q[i]

    ``rate`` ``(K, N)`` and ``hover_rate`` ``P`` ``(N,)`` in bit/s, ``buf`` ``(N,)`` bit,
    ``caps_s`` ``(K,)`` and ``hover_s`` ``H`` in s, starting prices ``lam_guess`` ``(N,)`` >= 0,
    ``lp_method`` the HiGHS method of every restricted LP. The value equals the every-column
    LP's to :data:`COLUMN_TOL` relative and is never below :func:`lagrangian_bound` at the
    returned prices (a certified upper bound). ``transit_s`` is ``s`` and ``hover_s`` is ``h``.
    """
    chosen = _near_best(rate, caps_s, lam_guess)
    rounds = 0
    while True:
        bits, lam, serve, hover, status = _restricted_lp(
            rate, buf, caps_s, hover_s, hover_rate, chosen, lp_method
        )
        rounds += 1
        certified = lagrangian_bound(rate, buf, caps_s, hover_s, hover_rate, lam)
        grown = chosen | _near_best(rate, caps_s, lam)
        if certified <= bits + COLUMN_TOL * max(1.0, abs(bits)) or np.array_equal(grown, chosen):
            return PrefixSolution(
                bits=max(bits, certified),
                lam=lam,
                transit_s=serve,
                hover_s=hover,
                status=status,
                rounds=rounds,
            )
        chosen = grown


def prefix_lp_columns(
    rate: np.ndarray,
    buf: np.ndarray,
    slot_s: float,
    n_slots: int,
    last: int,
    lam_guess: np.ndarray,
    lp_method: str,
) -> PrefixSolution:
    """``V(L)`` by column generation, starting from prices ``lam_guess`` (``(N,)``, >= 0).

    Same arguments as :func:`prefix_lp`; see :func:`time_sharing_columns`.
    """
    pre = rate[: last + 1]
    caps = np.full(last + 1, slot_s)
    hover = (n_slots - 1 - last) * slot_s
    return time_sharing_columns(pre, buf, caps, hover, pre.max(axis=0), lam_guess, lp_method)
