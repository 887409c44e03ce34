"""Tests for :mod:`skymule.bounds.fixed`: hand-solved cases, brute force and a reference MILP."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import Bounds, LinearConstraint, milp

from skymule.bounds.fixed import fixed_path_bound
from skymule.bounds.result import BoundError, BoundResult

REL = 1e-6


def _bound(rate, buf, dt, t, **kw) -> float:
    res = fixed_path_bound(np.asarray(rate, float), np.asarray(buf, float), dt, t, **kw)
    assert isinstance(res, BoundResult)
    return res.upper_bound_bit


# --- (a) one sensor, constant rate ---------------------------------------------------------


@pytest.mark.parametrize("hover", [True, False])
@pytest.mark.parametrize(("buf", "expected"), [(1e9, 2.0 * 5 * 0.5), (3.0, 3.0)])
def test_single_sensor_constant_rate(hover: bool, buf: float, expected: float) -> None:
    rate = np.full((5, 1), 2.0)
    assert _bound(rate, [buf], 0.5, 5, hover_allowed=hover) == pytest.approx(expected, rel=REL)


# --- (b) two sensors, step rates -----------------------------------------------------------

STEP_RATE = np.array([[4.0, 0.0], [4.0, 0.0], [0.0, 6.0], [0.0, 6.0]])


def test_two_sensors_step_rates() -> None:
    # A (Q=10) is heard at samples 0-1 at 4 bit/s, B (Q=100) at samples 2-3 at 6 bit/s; T=6.
    # Best: the two slots at A (8 bit), then every other second at B: 4 s x 6 = 24 -> 32.
    res = fixed_path_bound(STEP_RATE, np.array([10.0, 100.0]), 1.0, 6)
    assert res.upper_bound_bit == pytest.approx(32.0, rel=REL)
    assert res.dwell_time_s.sum() == pytest.approx(6.0)
    assert res.served_time_s[:2, 0].sum() == pytest.approx(2.0)
    assert res.last_sample >= 2
    # Small B buffer: both buffers fill (A: 2 s, B: 3.5 s of 6 s) -> 10 + 20.
    assert _bound(STEP_RATE, [10.0, 20.0], 1.0, 6) == pytest.approx(30.0, rel=REL)


# --- (c) waiting at the first sample -------------------------------------------------------


@pytest.mark.parametrize(("buf", "expected"), [(1e9, 40.0), (25.0, 25.0)])
def test_waiting_at_first_sample(buf: float, expected: float) -> None:
    rate = np.array([[10.0], [0.0], [0.0], [0.0]])
    res = fixed_path_bound(rate, np.array([buf]), 1.0, 4)
    assert res.upper_bound_bit == pytest.approx(expected, rel=REL)
    assert res.last_sample == 0
    assert _bound(rate, [buf], 1.0, 4, hover_allowed=False) == pytest.approx(10.0, rel=REL)


# --- (d) trace versus hold-at-end ----------------------------------------------------------


def test_trace_versus_hold() -> None:
    rate = np.array([[1.0], [3.0]])
    hold = _bound(rate, [1e9], 1.0, 5, hover_allowed=False, hold_at_end=True)
    trace = _bound(rate, [1e9], 1.0, 5, hover_allowed=False, hold_at_end=False)
    assert hold == pytest.approx(1.0 + 4 * 3.0, rel=REL)  # 4 slots held at the last sample
    assert trace == pytest.approx(1.0 + 3.0, rel=REL)  # mission ends after the path
    for hold_at_end in (True, False):  # with hover a trace may pause at the end: no difference
        got = _bound(rate, [1e9], 1.0, 5, hold_at_end=hold_at_end)
        assert got == pytest.approx(13.0, rel=REL)


# --- (e) brute force and reference MILP ----------------------------------------------------


def _best_schedule(rate: np.ndarray, buf: np.ndarray, n_slots: int, hover: bool, hold: bool):
    """Best total over every integral schedule (dt = 1), simulating y = min(R dt, Q)."""
    k_max, n = rate.shape

    def go(t: int, k: int, left: tuple[float, ...]) -> float:
        if t == n_slots:
            return 0.0
        best = 0.0
        for i in range(n):
            y = min(rate[k, i], left[i])
            rest = (*left[:i], left[i] - y, *left[i + 1 :])
            moves = [True, False] if hover else [True]
            for move in moves:
                nk = k + 1 if move else k
                if nk == k_max:
                    if not hold:
                        best = max(best, y)
                        continue
                    nk = k_max - 1
                best = max(best, y + go(t + 1, nk, rest))
        return best

    return go(0, 0, tuple(buf))


def _reference_milp(rate: np.ndarray, buf: np.ndarray, dt: float, n_slots: int) -> float:
    """The pause-anywhere MILP with binaries m_k, solved by HiGHS branch-and-bound."""
    k = min(rate.shape[0], n_slots)
    r = rate[:k]
    n = r.shape[1]
    kn = k * n
    eye = sp.eye_array(k)
    zk = sp.csr_array((k, k))
    a = sp.vstack(
        [
            sp.hstack([sp.kron(eye, np.ones((1, n))), -eye, zk]),
            sp.hstack(
                [
                    sp.csr_array((r.ravel(), (np.tile(np.arange(n), k), np.arange(kn)))),
                    sp.csr_array((n, 2 * k)),
                ]
            ),
            sp.hstack([sp.csr_array((k, kn)), -eye, dt * eye]),
            sp.hstack([sp.csr_array((k, kn)), eye, -sp.diags_array((n_slots - np.arange(k)) * dt)]),
            sp.hstack(
                [
                    sp.csr_array((k - 1, kn + k)),
                    sp.eye_array(k - 1, k, k=1) - sp.eye_array(k - 1, k),
                ]
            ),
            sp.hstack([sp.csr_array((1, kn)), np.ones((1, k)), sp.csr_array((1, k))]),
        ],
        format="csr",
    )
    ub = np.concatenate([np.zeros(k), buf, np.zeros(3 * k - 1), [n_slots * dt]])
    lb = np.concatenate([np.full(4 * k - 1 + n, -np.inf), [n_slots * dt]])
    lo = np.zeros(kn + 2 * k)
    lo[kn + k] = 1.0
    hi = np.concatenate([np.full(kn + k, np.inf), np.ones(k)])
    integ = np.concatenate([np.zeros(kn + k), np.ones(k)])
    res = milp(
        np.concatenate([-r.ravel(), np.zeros(2 * k)]),
        constraints=LinearConstraint(a, lb, ub),
        bounds=Bounds(lo, hi),
        integrality=integ,
        options={"mip_rel_gap": 1e-12},
    )
    return float(-res.fun)


def test_bound_dominates_brute_force_and_matches_milp() -> None:
    rng = np.random.default_rng(20240611)
    for _ in range(200):
        k = int(rng.integers(1, 5))
        n = int(rng.integers(1, 3))
        t = int(rng.integers(1, 5))
        rate = rng.uniform(0.0, 5.0, size=(k, n)) * (rng.random((k, n)) < 0.8)
        buf = rng.uniform(0.0, 12.0, size=n)
        hover_ub = _bound(rate, buf, 1.0, t)
        assert hover_ub == pytest.approx(_reference_milp(rate, buf, 1.0, t), rel=REL, abs=1e-9)
        for hold in (True, False):
            tol = 1e-7 * max(1.0, hover_ub)
            assert hover_ub >= _best_schedule(rate, buf, t, True, hold) - tol
            plain_ub = _bound(rate, buf, 1.0, t, hover_allowed=False, hold_at_end=hold)
            assert plain_ub >= _best_schedule(rate, buf, t, False, hold) - tol
            assert plain_ub <= hover_ub + tol


def test_result_shapes() -> None:
    rate = np.array([[1.0, 2.0], [3.0, 0.5], [0.0, 4.0]])
    for hover in (True, False):
        res = fixed_path_bound(rate, np.array([5.0, 5.0]), 2.0, 7, hover_allowed=hover)
        assert res.served_time_s.shape == (3, 2)
        assert res.dwell_time_s.shape == (3,)
        assert np.all(res.served_time_s.sum(axis=1) <= res.dwell_time_s + 1e-9)
        assert res.dwell_time_s.sum() == pytest.approx(14.0)
        assert res.solve_time_s >= 0.0
        assert "HiGHS" in res.method


# --- errors --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("rate", "buf", "dt", "t"),
    [
        ([[-1.0]], [1.0], 1.0, 1),
        ([[1.0]], [-1.0], 1.0, 1),
        ([[1.0, 2.0]], [1.0], 1.0, 1),
        ([1.0, 2.0], [1.0], 1.0, 1),
        ([[1.0]], [1.0], 0.0, 1),
        ([[1.0]], [1.0], 1.0, 0),
    ],
)
def test_invalid_inputs(rate, buf, dt, t) -> None:
    with pytest.raises(BoundError) as info:
        fixed_path_bound(np.asarray(rate), np.asarray(buf), dt, t)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)
