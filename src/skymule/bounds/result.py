"""What the bounds return: one-line errors and results, shared by every bound."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.units import BITS_PER_MBIT


class BoundError(SkymuleError):
    """Invalid input to a bound computation, or a scenario it does not support (one line)."""


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
        warnings: conditions of the method that visibly fail for this mission (one line each).
    """

    upper_bound_bit: float
    method: str
    status: str
    solve_time_s: float
    served_time_s: np.ndarray
    dwell_time_s: np.ndarray
    last_sample: int
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class MissionBound:
    """An upper bound for one scenario, as ``skymule bound`` reports it: bits inside (SI, as
    every engine), Mbit at the edge (``upper_bound_mbit``, ``to_json_dict``).

    Attributes:
        scenario: scenario name.
        mode: ``trajectory.mode`` ("fixed" or "autonomous").
        upper_bound_bit: bound on the bits any policy downloads (bit).
        method: relaxation and solver used.
        status: solver status.
        solve_time_s: wall-clock solve time (s).
        total_buffer_bit: sum of the initial buffers (bit).
        no_hover_upper_bound_bit: fixed trajectories: the paper's formulation with ``r_t``
            fixed (no pausing), in bit; None for autonomous ones.
        warnings: conditions of the method that visibly fail for this mission (one line
            each); ``skymule bound`` and ``compare`` print them.
    """

    scenario: str
    mode: str
    upper_bound_bit: float
    method: str
    status: str
    solve_time_s: float
    total_buffer_bit: float
    no_hover_upper_bound_bit: float | None = None
    warnings: tuple[str, ...] = ()

    @property
    def upper_bound_mbit(self) -> float:
        """The bound in Mbit, as summaries, comparisons and ``bound.json`` give data."""
        return self.upper_bound_bit / BITS_PER_MBIT

    @property
    def no_hover_upper_bound_mbit(self) -> float | None:
        """The paper's no-pause bound in Mbit (fixed paths; None for autonomous ones)."""
        no_hover = self.no_hover_upper_bound_bit
        return None if no_hover is None else no_hover / BITS_PER_MBIT

    @property
    def total_buffer_mbit(self) -> float:
        return self.total_buffer_bit / BITS_PER_MBIT

    def to_json_dict(self) -> dict[str, Any]:
        """The ``bound.json`` record (Mbit at the edge)."""
        return {
            "scenario": self.scenario,
            "mode": self.mode,
            "upper_bound_mbit": self.upper_bound_mbit,
            "no_hover_upper_bound_mbit": self.no_hover_upper_bound_mbit,
            "total_buffer_mbit": self.total_buffer_mbit,
            "method": self.method,
            "status": self.status,
            "solve_time_s": self.solve_time_s,
            "warnings": list(self.warnings),
        }
