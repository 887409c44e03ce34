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
Variables: ``s[k, i] >= 0`` seconds spent serving sensor ``i`` at sample ``k``,
``d[k] >= 0`` seconds spent at sample ``k`` (dwell) and binaries ``m[k]`` (sample ``k`` is
reached)::

    maximise   sum_{k,i} R[k,i] s[k,i]                         (bit)
    s.t.       sum_i s[k,i]            <= d[k]                  (time sharing within a sample)
               sum_k R[k,i] s[k,i]     <= Q[i]                  (buffer, eqs. 8-9)
               dt m[k] <= d[k] <= (T - k) dt m[k]                (reached <=> at least one slot)
               m[0] = 1,  m[k] >= m[k+1],  m binary             (path-prefix structure)
               sum_k d[k] = T dt                                (mission length)

Take any integral schedule obeying the rules. Put ``d[k] = dt * (#slots spent at k)``,
``m[k] = 1`` iff sample ``k`` is visited, and for a slot at ``k`` serving ``i`` add
``y / R[k, i] <= dt`` to ``s[k, i]``. Samples are visited in order without gaps, so ``m`` is a
prefix indicator; every visited sample hosts at least one slot (the UAV is there in the slot
it arrives in); before reaching ``k`` the UAV spent ``k`` moving slots at earlier samples, so
at most ``T - k`` slots are at ``k``. Downloads never exceed the buffer, so the buffer rows
hold, and the objective equals the schedule's collected bits. If a trace mission ends early
(moved past ``K - 1``) the unused time is added to ``d[K - 1]``, which keeps every row true.
Hence the optimum is an upper bound on every policy; the relaxation lies in letting slots be
time-shared and letting the pause time at a sample be any real amount.

When hover is allowed ``hold_at_end`` makes no difference: a trace policy can always pause at
``K - 1`` until the end, which is exactly what holding does. Only ``min(K, T)`` samples can be
reached, so later samples are dropped from the model.

The binaries are needed: the LP relaxation of ``m`` lets the UAV reach a far sample while
paying only a fraction of the transit time, and the optimal value as a function of the last
sample ``L`` is not concave, so neither the LP relaxation nor a monotone search is exact.
(Enumerating ``L`` is exact but costs ``min(K, T)`` LPs.) The model is small and sparse
(``K (N + 2)`` columns), and HiGHS closes it quickly in practice. The reported
``upper_bound_bit`` is HiGHS' *dual* bound (valid even if the gap were not closed) with
``mip_rel_gap`` set to 1e-9.

Hover not allowed: the paper's formulation
------------------------------------------
With ``r_t`` fixed the UAV is at sample ``min(t, K - 1)`` in slot ``t`` (``hold_at_end``), or
slot ``t`` exists only for ``t < min(T, K)`` (trace). The paper's program is an LP over the
association ``x[t, i] in [0, 1]``, ``sum_i x[t, i] <= 1``, ``sum_t x[t, i] R dt <= Q[i]``,
maximising ``sum x R dt``. Any integral association with ``y = min(R dt, Q_i)`` maps to
``x = y / (R dt)``, so the LP bounds the integral problem. Slots at the same sample have the
same rates, so we aggregate them: ``s[k, i] = sum_{t at k} x[t, i] dt`` with
``sum_i s[k, i] <= c_k dt`` where ``c_k`` is the number of slots at ``k``. This has the same
optimum and ``K x N`` rather than ``T x N`` columns.

``max_hover_s`` (an HGAD-style cap on a single pause) is *not* part of the bound: dropping a
constraint can only raise the optimum, so the bound stays valid for capped policies. It is
accepted and validated so callers can pass their policy parameters unchanged.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import Bounds, LinearConstraint, OptimizeResult, linprog, milp

__all__ = ["BoundError", "BoundResult", "fixed_path_bound"]

#: Relative MIP gap handed to HiGHS; the bound reported is the dual bound either way.
MIP_REL_GAP = 1e-9


class BoundError(ValueError):
    """Invalid input to a bound computation (one-line message)."""


@dataclass(frozen=True)
class BoundResult:
    """Result of :func:`fixed_path_bound`.

    Attributes:
        upper_bound_bit: upper bound on the bits any admissible policy collects (bit).
        method: human-readable description of the relaxation and solver.
        status: solver status message.
        solve_time_s: wall-clock time spent building and solving the model (s).
        served_time_s: ``(K, N)`` seconds spent serving sensor ``i`` at sample ``k`` in the
            optimal relaxed solution.
        dwell_time_s: ``(K,)`` seconds spent at sample ``k``.
        last_sample: index of the last sample reached.
    """

    upper_bound_bit: float
    method: str
    status: str
    solve_time_s: float
    served_time_s: np.ndarray
    dwell_time_s: np.ndarray
    last_sample: int


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


def _serve_block(rate: np.ndarray, buf: np.ndarray) -> tuple[sp.csr_array, sp.csr_array]:
    """Sparse rows shared by both models, over the ``K * N`` serve columns (row-major).

    Returns ``(A_time, A_buf)``: ``A_time`` is ``(K, K N)`` with ``A_time @ s = sum_i s[k, i]``
    and ``A_buf`` is ``(N, K N)`` with ``A_buf @ s = sum_k R[k, i] s[k, i]`` (bit).
    """
    k, n = rate.shape
    a_time = sp.kron(sp.eye_array(k), np.ones((1, n)), format="csr")
    a_buf = sp.csr_array(
        (rate.ravel(), (np.tile(np.arange(n), k), np.arange(k * n))), shape=(n, k * n)
    )
    return a_time, a_buf


def _fixed_dwell_lp(
    rate: np.ndarray, buf: np.ndarray, dwell_s: np.ndarray
) -> tuple[float, str, np.ndarray]:
    """LP optimum with the dwell per sample fixed: returns ``(bits, status, s (K, N))``."""
    k, n = rate.shape
    a_time, a_buf = _serve_block(rate, buf)
    res = linprog(
        -rate.ravel(),
        A_ub=sp.vstack([a_time, a_buf], format="csr"),
        b_ub=np.concatenate([dwell_s, buf]),
        bounds=(0, None),
        method="highs",
    )
    if res.status != 0:
        raise RuntimeError(f"HiGHS failed on the no-hover LP: {res.message}")
    return float(-res.fun), str(res.message), np.reshape(res.x, (k, n))


def _hover_milp(
    rate: np.ndarray, buf: np.ndarray, slot_s: float, n_slots: int
) -> tuple[float, OptimizeResult]:
    """Solve the pause-anywhere MILP over ``K`` samples (``K <= T``).

    Columns: ``s`` (``K N``, s), ``d`` (``K``, s), ``m`` (``K``, binary). Returns the dual
    bound (bit) and the raw result.
    """
    k, n = rate.shape
    kn = k * n
    a_time, a_buf = _serve_block(rate, buf)
    eye = sp.eye_array(k, format="csr")
    zero_kn = sp.csr_array((k, kn))
    # sum_i s[k, i] - d[k] <= 0
    rows_time = sp.hstack([a_time, -eye, sp.csr_array((k, k))])
    # buffers
    rows_buf = sp.hstack([a_buf, sp.csr_array((n, 2 * k))])
    # dt m[k] - d[k] <= 0  and  d[k] - (T - k) dt m[k] <= 0
    rows_low = sp.hstack([zero_kn, -eye, slot_s * eye])
    cap = sp.diags_array((n_slots - np.arange(k)) * slot_s)
    rows_high = sp.hstack([zero_kn, eye, -cap])
    # m[k+1] - m[k] <= 0
    diff = sp.eye_array(k - 1, k, k=1) - sp.eye_array(k - 1, k)
    rows_mono = sp.hstack([sp.csr_array((k - 1, kn + k)), diff])
    # sum d = T dt
    rows_total = sp.hstack(
        [sp.csr_array((1, kn)), np.ones((1, k)), sp.csr_array((1, k))]
    )
    a = sp.vstack([rows_time, rows_buf, rows_low, rows_high, rows_mono, rows_total], format="csr")
    total = n_slots * slot_s
    upper = np.concatenate([np.zeros(k), buf, np.zeros(2 * k + k - 1), [total]])
    lower = np.concatenate([np.full(k, -np.inf), np.full(n, -np.inf),
                            np.full(2 * k + k - 1, -np.inf), [total]])
    lb = np.zeros(kn + 2 * k)
    ub = np.full(kn + 2 * k, np.inf)
    ub[kn + k:] = 1.0
    lb[kn + k] = 1.0  # m[0] = 1
    integrality = np.zeros(kn + 2 * k)
    integrality[kn + k:] = 1
    res = milp(
        np.concatenate([-rate.ravel(), np.zeros(2 * k)]),
        constraints=LinearConstraint(a, lower, upper),
        bounds=Bounds(lb, ub),
        integrality=integrality,
        options={"mip_rel_gap": MIP_REL_GAP},
    )
    if res.x is None:
        raise RuntimeError(f"HiGHS failed on the fixed-path MILP: {res.message}")
    dual = getattr(res, "mip_dual_bound", None)
    bound = float(-dual) if dual is not None and np.isfinite(dual) else float(-res.fun)
    return bound, res


def fixed_path_bound(
    rate_bps: np.ndarray,
    buffers_bit: np.ndarray,
    slot_s: float,
    n_slots: int,
    *,
    hover_allowed: bool = True,
    hold_at_end: bool = True,
    max_hover_s: float | None = None,
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

    Returns:
        A :class:`BoundResult`; ``served_time_s`` is ``(K, N)`` and ``dwell_time_s`` ``(K,)``.

    Raises:
        BoundError: on negative or non-finite rates or buffers, shape mismatch, ``slot_s <= 0``
            or ``n_slots < 1``.
    """
    rate, buf = _validate(rate_bps, buffers_bit, slot_s, n_slots, max_hover_s)
    n_samples, n_sensors = rate.shape
    n_slots = int(n_slots)
    slot_s = float(slot_s)
    start = time.perf_counter()
    served = np.zeros((n_samples, n_sensors))
    dwell = np.zeros(n_samples)
    if hover_allowed:
        reach = min(n_samples, n_slots)
        bound, res = _hover_milp(rate[:reach], buf, slot_s, n_slots)
        x = res.x
        kn = reach * n_sensors
        served[:reach] = np.reshape(x[:kn], (reach, n_sensors))
        dwell[:reach] = x[kn : kn + reach]
        reached = np.flatnonzero(x[kn + reach :] > 0.5)
        last = int(reached[-1])
        status = str(res.message)
        method = "fixed-path MILP: pause anywhere, time-shared slots (HiGHS)"
    else:
        counts = no_hover_slot_counts(n_samples, n_slots, hold_at_end=hold_at_end)
        dwell = counts * slot_s
        bound, status, served = _fixed_dwell_lp(rate, buf, dwell)
        last = int(np.flatnonzero(counts)[-1])
        semantics = "hold at end" if hold_at_end else "trace ends at last sample"
        method = f"fixed-path LP: no hover ({semantics}), fractional association (HiGHS)"
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
