"""Upper bounds on the data a UAV data mule can collect along a fixed trajectory.

Setting and notation (SI units throughout: bit, bit/s, s)
---------------------------------------------------------
The mission has ``T`` slots of ``dt`` seconds. The UAV follows a fixed path given as ``K``
track samples; sample ``k`` is where it is after ``k`` moving slots. ``R[k, i] >= 0`` is the
rate (bit/s) to sensor ``i`` at sample ``k`` and ``Q[i]`` the sensor's buffer (bit). In every
slot the UAV sits at one sample and downloads from at most one sensor, ``y = min(R dt, Q_i)``
where ``Q_i`` is what is left in that buffer (the paper's eqs. 8-9, ``Q_i(t) >= 0``). A slot
either *moves* (``k -> k + 1``) or *pauses* (hovers, ``k`` unchanged). With
``hold_at_end=True`` (model-based path) the UAV stays at ``K - 1`` once there; with
``hold_at_end=False`` (recorded trace) the mission ends when it moves past ``K - 1``.

Hover allowed: the relaxation and why it bounds every policy
------------------------------------------------------------
Relaxed problem (the MILP of the brief): ``s[k, i] >= 0`` seconds serving sensor ``i`` at
sample ``k``, dwell ``d[k]``, binaries ``m[k]`` (sample ``k`` reached)::

    max  sum R[k,i] s[k,i]   s.t.  sum_i s[k,i] <= d[k],  sum_k R[k,i] s[k,i] <= Q[i],
         dt m[k] <= d[k] <= (T - k) dt m[k],  1 = m[0] >= m[1] >= ...,  sum_k d[k] = T dt.

Validity: map any integral schedule to ``d[k] = dt * #slots at k``, ``m`` = visited samples
(a prefix, since samples are visited in order), and for a slot at ``k`` serving ``i`` add
``y / R[k, i] <= dt`` to ``s[k, i]``. Each visited sample hosts at least the slot the UAV
arrives in; at most ``T - k`` slots are at ``k`` (``k`` moving slots came first); downloads
never exceed the buffers; a trace mission that ends early puts its unused time on
``d[K - 1]``. So the optimum bounds every policy. With hover, ``hold_at_end`` is irrelevant
(a trace policy may pause at ``K - 1`` until the end) and only samples ``< min(K, T)`` count.

Exact solution without branch-and-bound. Fix the last sample ``L`` (``m`` = prefix
``0..L``). Every sample ``k <= L`` has one mandatory slot; the rest,
``H_L = (T - L - 1) dt``, is pause time placeable anywhere in ``0..L``. Pause time spent on
sensor ``i`` is best placed at ``P_L[i] = max_{k<=L} R[k, i]``: moving it there keeps the
bits and uses less time. So ``V(L)`` is the LP *prefix LP*: ``s[k, i]`` with
``sum_i s[k, i] <= dt`` (``k <= L``), hover columns ``h_i`` with ``sum_i h_i <= H_L``, and
``sum_k R[k, i] s[k, i] + P_L[i] h_i <= Q[i]``; the answer is ``max_L V(L)``.

* Only *record samples* need checking: ``L = 0`` and the ``L`` where some ``R[L, i]`` beats
  every earlier sample. If ``R[L + 1] <= P_L`` componentwise then ``P_{L+1} = P_L`` and the
  mandatory slot at ``L + 1`` can be replaced by a hover slot at rates ``P_L`` that are at least
  as good, so ``V(L + 1) <= V(L)``.
* LP duality gives, for any buffer price ``lam >= 0`` and every ``L`` at once,
  ``V(L) <= Phi_L(lam) = lam.Q + dt sum_{k<=L} g_k + H_L max_{k<=L} g_k`` with
  ``g_k = max(0, max_i R[k, i] (1 - lam_i))`` (``O(K N)`` with cumsum / cummax). We solve the
  candidate with the largest bound, tighten every bound with its optimal prices, and stop
  when no unsolved candidate's bound beats the incumbent (relative ``PRUNE_TOL``). The result
  equals the MILP optimum (``V`` as a function of ``L`` is not concave and the MILP's LP
  relaxation is loose — it averages buffers over a mixture of path lengths — which is why
  HiGHS branch-and-bound on ``m`` took minutes at 3,600 slots while this takes seconds).
  ``upper_bound_bit`` is ``max(incumbent, largest unsolved bound)``, so it stays a bound.
* Each prefix LP is solved by column generation (:mod:`skymule.bounds.prefix_lp`): an LP over
  the few columns that are near-best in their slot at the buffer prices that gave the
  candidate its current bound, grown until ``Phi_L`` at its own prices certifies it (the value
  reported is never below that certified bound). ``solver="full"`` solves every prefix LP
  with all its ``(L + 1) N`` columns instead: the plain reference, tested equal.

Hover not allowed: the paper's formulation
------------------------------------------
With ``r_t`` fixed the UAV is at sample ``min(t, K - 1)`` in slot ``t`` (``hold_at_end``), or
slot ``t`` exists only for ``t < min(T, K)`` (trace). The paper's program is an LP over the
association ``x[t, i] in [0, 1]``, ``sum_i x[t, i] <= 1``, ``sum_t x[t, i] R dt <= Q[i]``,
maximising ``sum x R dt``. Any integral association with ``y = min(R dt, Q_i)`` maps to
``x = y / (R dt)``, so the LP bounds the integral problem. Slots at the same sample have the
same rates, so we aggregate them: ``s[k, i] = sum_{t at k} x[t, i] dt`` with
``sum_i s[k, i] <= c_k dt`` where ``c_k`` is the number of slots at ``k``. This has the same
optimum and ``K x N`` rather than ``T x N`` columns. It is solved by the same column generation
(no hover time; ``c_k dt`` per sample), or with every column under ``solver="full"``.

``max_hover_s`` (an HGAD-style cap on a single pause) is *not* part of the bound: dropping a
constraint can only raise the optimum, so the bound stays valid for capped policies. It is
accepted and validated so callers can pass their policy parameters unchanged.

Scenarios: :func:`mission_bound`
--------------------------------
:func:`mission_bound` bounds a built :class:`~skymule.world.Mission` through a registry keyed
by ``trajectory.mode``. Fixed trajectories (model, radio-map or trace source alike: each gives
a ``Track``) use the rates ``mission.rate_bps(track.snr_db)``, ``hold_at_end`` of the track and
``T = mission.n_slots``, and report both the pause-anywhere bound and the paper's no-hover LP.
Autonomous trajectories call ``skymule.bounds.autonomous.autonomous_bound`` (imported lazily).

On fixed trajectories, per-slot small-scale fading (``radio.fading != "none"``) is refused
(the autonomous bound models it itself): the UAV then sees
``f(SNR_track[k] + fading[t])``, a rate that depends on the slot as well as the sample, so the
track-only programs above are not bounds for it. The only valid track-based repair (each
sample's rate maximised over the slots that could visit it) adds the largest fading draw of
the mission to every sample and says little; a slot-by-sample formulation is future work.
Spatial shadowing is deterministic per seed and part of the track, so it is supported.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

from skymule.bounds.prefix_lp import (
    PrefixSolution,
    dual_bounds,
    prefix_lp,
    prefix_lp_columns,
    time_sharing_columns,
)
from skymule.bounds.result import BoundError, BoundResult, MissionBound

if TYPE_CHECKING:
    from skymule.world import Mission

__all__ = [
    "fixed_mission_bound",
    "fixed_path_bound",
    "mission_track_rates",
]

#: HiGHS method for every bound LP. The interior-point method (with crossover, so the solution
#: is a vertex with duals) gives the same optima as the default dual simplex on every bound
#: test and is 2.6-15x faster at 3,600 slots; at 36,000 slots the simplex does not finish in
#: 10 minutes. ``"highs"`` stays selectable (``lp_method=``) for comparisons.
LP_METHOD = "highs-ipm"

#: How every LP of the bound is solved: ``"columns"`` (column generation, the default; see
#: :mod:`skymule.bounds.prefix_lp`) or ``"full"`` (the plain reference, every column in one LP;
#: the method before column generation).
SOLVERS = ("columns", "full")

#: Relative tolerance for pruning a last sample whose dual bound does not beat the incumbent.
PRUNE_TOL = 1e-9


def _validate(
    rate_bps: np.ndarray,
    buffers_bit: np.ndarray,
    slot_s: float,
    n_slots: int,
    max_hover_s: float | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Check inputs and return ``(R, Q)`` as float arrays of shapes ``(K, N)`` and ``(N,)``."""
    rate = np.asarray(rate_bps, dtype=float)
    buf = np.asarray(buffers_bit, dtype=float)
    if rate.ndim != 2 or rate.shape[0] < 1 or rate.shape[1] < 1:
        raise BoundError(f"rate_bps must be a non-empty (K, N) array, got shape {rate.shape}")
    if buf.shape != (rate.shape[1],):
        raise BoundError(
            f"buffers_bit must have shape ({rate.shape[1]},) to match rate_bps, got {buf.shape}"
        )
    if not np.all(np.isfinite(rate)) or np.any(rate < 0):
        raise BoundError("rate_bps must be finite and >= 0")
    if not np.all(np.isfinite(buf)) or np.any(buf < 0):
        raise BoundError("buffers_bit must be finite and >= 0")
    if not np.isfinite(slot_s) or slot_s <= 0:
        raise BoundError(f"slot_s must be a finite number > 0, got {slot_s}")
    if isinstance(n_slots, bool) or int(n_slots) != n_slots or n_slots < 1:
        raise BoundError(f"n_slots must be an integer >= 1, got {n_slots}")
    if max_hover_s is not None and not (np.isfinite(max_hover_s) and max_hover_s >= 0):
        raise BoundError(f"max_hover_s must be None or a finite number >= 0, got {max_hover_s}")
    return rate, buf


def no_hover_slot_counts(n_samples: int, n_slots: int, *, hold_at_end: bool) -> np.ndarray:
    """Slots spent at each sample when the UAV never pauses.

    Returns a ``(K,)`` int array: one slot per sample for the first ``min(K, T)`` samples and,
    with ``hold_at_end``, the ``T - K`` leftover slots added to sample ``K - 1``.
    """
    counts = (np.arange(n_samples) < n_slots).astype(np.int64)
    if hold_at_end and n_slots > n_samples:
        counts[-1] += n_slots - n_samples
    return counts


def _fixed_dwell_lp(
    rate: np.ndarray, buf: np.ndarray, dwell_s: np.ndarray, lp_method: str, solver: str
) -> tuple[float, str, np.ndarray]:
    """LP optimum with the dwell per sample fixed: returns ``(bits, status, s (K, N))``.

    ``solver="columns"``: column generation (no hover time); ``"full"``: every column.
    """
    k, n = rate.shape
    if solver == "columns":
        zero = np.zeros(n)
        sol = time_sharing_columns(rate, buf, dwell_s, 0.0, zero, zero, lp_method)
        return sol.bits, f"{sol.status} ({sol.rounds} HiGHS solves)", sol.transit_s
    a_time = sp.kron(sp.eye_array(k), np.ones((1, n)), format="csr")
    a_buf = sp.csr_array(
        (rate.ravel(), (np.tile(np.arange(n), k), np.arange(k * n))), shape=(n, k * n)
    )
    res = linprog(
        -rate.ravel(),
        A_ub=sp.vstack([a_time, a_buf], format="csr"),
        b_ub=np.concatenate([dwell_s, buf]),
        bounds=(0, None),
        method=lp_method,
    )
    if res.status != 0:
        raise RuntimeError(f"HiGHS failed on the no-hover LP: {res.message}")
    return float(-res.fun), str(res.message), np.reshape(res.x, (k, n))


def record_samples(rate: np.ndarray) -> np.ndarray:
    """Indices ``k`` where some sensor's rate beats every earlier sample (``k = 0`` included).

    ``rate`` is ``(K, N)`` (bit/s); returns a sorted ``(C,)`` int array.
    """
    best_before = np.maximum.accumulate(rate, axis=0)[:-1]
    improves = np.any(rate[1:] > best_before, axis=1)
    return np.concatenate([[0], 1 + np.flatnonzero(improves)])


def _hover_search(
    rate: np.ndarray,
    buf: np.ndarray,
    slot_s: float,
    n_slots: int,
    lp_method: str,
    solver: str,
) -> tuple[float, PrefixSolution, int, int, int]:
    """Exact ``max_L V(L)`` over record samples, pruned with dual bounds.

    ``solver`` is ``"columns"`` (column generation, warm-started from the prices that
    gave the candidate its current bound) or ``"full"`` (the reference: every column, with
    ``lp_method``). Returns ``(upper bound, best solution, its L, prefix LPs, HiGHS solves)``.
    """
    candidates = record_samples(rate)
    n_sensors = rate.shape[1]
    upper = dual_bounds(rate, buf, slot_s, n_slots, np.zeros(n_sensors))[candidates]
    prices = [np.zeros(n_sensors)]  # every price vector tried so far
    upper_from = np.zeros(candidates.size, dtype=np.int64)  # which one gave ``upper``
    solved = np.zeros(candidates.size, dtype=bool)
    best: PrefixSolution | None = None
    best_last = 0
    n_lp = n_solves = 0
    while True:
        open_ub = np.where(solved, -np.inf, upper)
        j = int(np.argmax(open_ub))
        lower = best.bits if best is not None else -np.inf
        if solved[j] or open_ub[j] <= lower + PRUNE_TOL * max(1.0, abs(lower)):
            break
        last = int(candidates[j])
        if solver == "full":
            sol = prefix_lp(rate, buf, slot_s, n_slots, last, lp_method)
        else:
            sol = prefix_lp_columns(
                rate, buf, slot_s, n_slots, last, prices[upper_from[j]], lp_method
            )
        n_lp += 1
        n_solves += sol.rounds
        solved[j] = True
        upper[j] = sol.bits
        if best is None or sol.bits > best.bits:
            best, best_last = sol, last
        phi = dual_bounds(rate, buf, slot_s, n_slots, sol.lam)[candidates]
        tighter = ~solved & (phi < upper)
        upper[tighter] = phi[tighter]
        upper_from[tighter] = len(prices)
        prices.append(sol.lam)
    assert best is not None
    remaining = np.where(solved, -np.inf, upper).max(initial=-np.inf)
    return max(best.bits, float(remaining)), best, best_last, n_lp, n_solves


def fixed_path_bound(
    rate_bps: np.ndarray,
    buffers_bit: np.ndarray,
    slot_s: float,
    n_slots: int,
    *,
    hover_allowed: bool = True,
    hold_at_end: bool = True,
    max_hover_s: float | None = None,
    lp_method: str = LP_METHOD,
    solver: str = "columns",
) -> BoundResult:
    """Upper bound on the bits collected along a fixed path (see the module docstring).

    Args:
        rate_bps: ``(K, N)`` rate to sensor ``i`` at track sample ``k`` (bit/s, >= 0).
        buffers_bit: ``(N,)`` buffer of each sensor at mission start (bit, >= 0).
        slot_s: slot length ``dt`` (s, > 0).
        n_slots: number of slots ``T`` in the mission (>= 1).
        hover_allowed: whether the UAV may pause (hover) at a sample.
        hold_at_end: model-based path (stay at ``K - 1``) versus recorded trace (mission ends
            after moving past ``K - 1``).
        max_hover_s: per-pause hover cap of the policy being bounded; ignored by the bound
            (which stays valid), only validated.
        lp_method: ``scipy.optimize.linprog`` HiGHS method of every LP (default
            :data:`LP_METHOD`).
        solver: ``"columns"`` (column generation, see :mod:`skymule.bounds.prefix_lp`) or
            ``"full"`` (the reference, every column); same bound to ~1e-9 relative.

    Returns:
        A :class:`BoundResult`; ``served_time_s`` is ``(K, N)`` and ``dwell_time_s`` ``(K,)``.

    Raises:
        BoundError: on negative or non-finite rates or buffers, shape mismatch, ``slot_s <= 0``
            or ``n_slots < 1``, or an unknown ``solver``.
    """
    rate, buf = _validate(rate_bps, buffers_bit, slot_s, n_slots, max_hover_s)
    if solver not in SOLVERS:
        raise BoundError(f"solver must be one of {SOLVERS}, got {solver!r}")
    n_samples, n_sensors = rate.shape
    n_slots = int(n_slots)
    slot_s = float(slot_s)
    start = time.perf_counter()
    served = np.zeros((n_samples, n_sensors))
    dwell = np.zeros(n_samples)
    how = "column generation" if solver == "columns" else "every column"
    if hover_allowed:
        reach = min(n_samples, n_slots)
        bound, sol, last, n_lp, n_solves = _hover_search(
            rate[:reach], buf, slot_s, n_slots, lp_method, solver
        )
        served[: last + 1] = sol.transit_s
        best_at = np.argmax(rate[: last + 1], axis=0)
        np.add.at(served, (best_at, np.arange(n_sensors)), sol.hover_s)
        dwell[: last + 1] = slot_s
        np.add.at(dwell, best_at, sol.hover_s)  # several sensors may share a best sample
        dwell[last] += n_slots * slot_s - dwell.sum()
        status = f"{sol.status} ({n_lp} prefix LPs, {n_solves} HiGHS solves)"
        method = (
            "fixed-path exact search: pause anywhere, time-shared slots "
            f"(prefix LPs by {how}, HiGHS {lp_method})"
        )
    else:
        counts = no_hover_slot_counts(n_samples, n_slots, hold_at_end=hold_at_end)
        dwell = counts * slot_s
        bound, status, served = _fixed_dwell_lp(rate, buf, dwell, lp_method, solver)
        last = int(np.flatnonzero(counts)[-1])
        semantics = "hold at end" if hold_at_end else "trace ends at last sample"
        method = (
            f"fixed-path LP: no hover ({semantics}), fractional association ({how}, "
            f"HiGHS {lp_method})"
        )
    elapsed = time.perf_counter() - start
    served = np.clip(served, 0.0, None)
    dwell = np.clip(dwell, 0.0, None)
    return BoundResult(
        upper_bound_bit=bound,
        method=method,
        status=status,
        solve_time_s=elapsed,
        served_time_s=served,
        dwell_time_s=dwell,
        last_sample=last,
    )


def mission_track_rates(mission: Mission) -> np.ndarray:
    """``(K, N)`` rate (bit/s) at every track sample of a fixed mission (NaN SNR: rate 0)."""
    if mission.track is None:
        raise BoundError(
            "bound: trajectory.mode = 'fixed' needs a track (trajectory.waypoints or "
            "signal.trace); none was built"
        )
    return np.asarray(mission.rate_bps(mission.track.snr_db), dtype=float)


def fixed_mission_bound(mission: Mission) -> MissionBound:
    """Pause-anywhere bound plus the paper's no-hover LP for a fixed trajectory."""
    fading = mission.scenario.radio.fading
    if fading != "none" or mission.fading_db is not None:
        raise BoundError(
            f"bound: radio.fading = {fading!r} is not supported on a fixed trajectory (per-slot "
            "fading makes the rate depend on the slot, not only on the track sample); "
            "set radio.fading = 'none'"
        )
    rate = mission_track_rates(mission)
    assert mission.track is not None
    args = (rate, mission.buffers_bit, mission.slot_s, mission.n_slots)
    hover = fixed_path_bound(*args, hover_allowed=True)
    no_hover = fixed_path_bound(*args, hover_allowed=False, hold_at_end=mission.track.hold_at_end)
    return MissionBound(
        scenario=mission.scenario.name,
        mode="fixed",
        upper_bound_bit=hover.upper_bound_bit,
        method=hover.method,
        status=hover.status,
        solve_time_s=hover.solve_time_s + no_hover.solve_time_s,
        total_buffer_bit=float(np.sum(mission.buffers_bit)),
        no_hover_upper_bound_bit=no_hover.upper_bound_bit,
    )
