"""Time left and the return-home deadline, over any shape (missions, rows).

The deadline has one form, whatever is spent on the way home: after slot t of a T-slot
mission, T - t - 1 slots are left, each worth ``per_slot`` (metres at the speed cap in calm
air, seconds of flight under a wind); the UAV may go elsewhere only while the way home costs
at most that budget (plus a round-off ``slack``). The battery's form is the same test in
joules, without slots: the energy used, plus a slot's move, plus the way home, stays within the
usable energy (``faults.motion.Battery.affords``).
"""

from __future__ import annotations

from typing import Any

#: Slack [m] of the return-home test (floating-point round-off only).
FEASIBILITY_SLACK_M = 1e-6


def time_left_s(n_slots: Any, slot: Any, slot_s: Any) -> Any:
    """Mission time left at the start of slot ``slot`` [s]: (T - t) dt (elementwise)."""
    return (n_slots - slot) * slot_s


def home_budget(n_slots: Any, slot: Any, per_slot: Any, slack: Any = 0.0) -> Any:
    """What the way home may cost from the position after slot ``slot``: (T - t - 1) x
    ``per_slot`` + ``slack`` (elementwise). The UAV is home by the mission's end when the way
    home from each slot's end position costs at most this; ``slot = t - 1`` gives what is
    left from the start of slot t."""
    return (n_slots - slot - 1) * per_slot + slack
