"""The reference engine's return-home override, for B missions at once.

With ``return_home`` the reference engine (:func:`skymule.sim.autonomous.next_position`)
overrides the policy's goal with home whenever the move would leave too little time to get
back: when d_home(position) + step > budget and d_home(moved) > budget, with
budget = (T - t - 1) step + FEASIBILITY_SLACK_M and d_home the in-fence distance home. The
batched autonomous engine (:mod:`skymule.sim.batch_autonomous`) applies the same test with
the same floats, but asks for d_home only where a bound cannot decide it: the in-fence
distance is at least the straight line and grows by at most one step per slot.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from skymule.sim.autonomous import FEASIBILITY_SLACK_M
from skymule.sim.batch_paths import Paths
from skymule.world import Mission

#: Margin [m] by which a bound on the distance home must clear the budget before the exact
#: distance is skipped (far above float round-off, far below a step).
BOUND_SLACK_M = 1e-3


class HomeDeadline:
    """The reference's return-home override, for B missions (``return_home`` ones only).

    The in-fence distance home is computed only where the override may bind: ``bound`` is an
    upper bound on it (exact where computed, plus one step per slot: no slot takes the UAV
    farther), and the distance from where a UAV ends a slot, computed to test the override,
    is kept as the exact distance at the start of the next one (the same query, the same
    float). A UAV that flies home anyway is left alone: the override would make the same move
    (only the ``hovering`` flag could differ, and only if it did not move).
    """

    def __init__(
        self,
        navigator: Paths,
        missions: Sequence[Mission],
        home_m: np.ndarray,
        home_sight: tuple[np.ndarray, np.ndarray],
    ) -> None:
        self._nav = navigator
        self._home = home_m
        self._sight = home_sight
        self._n_slots = np.array([m.n_slots for m in missions], np.int64)
        self._step = np.array([m.max_step_m for m in missions], float)
        self.on = np.array([m.return_home for m in missions], bool)
        self._bound = np.zeros(len(missions))
        self._exact = np.full(len(missions), np.nan)
        self._last = np.zeros(len(missions), bool)  # overridden in the last slot

    def _distances(self, rows: np.ndarray, points: np.ndarray) -> np.ndarray:
        sight = (self._sight[0][rows], self._sight[1][rows])
        return self._nav.travel_distances(points, self._home[rows], sight, checked=False)

    def _beeline(self, rows: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Straight-line distance home [m]: a lower bound on the in-fence distance."""
        return np.hypot(points[:, 0] - self._home[rows, 0], points[:, 1] - self._home[rows, 1])

    def likely(self, active: int) -> np.ndarray:
        """Rows among the first A whose goal was overridden last slot (likely again now): the
        engine computes their step home together with the policy's steps."""
        return np.flatnonzero(self._last[:active])

    def apply(
        self,
        slot: int,
        here: np.ndarray,
        moved: np.ndarray,
        flying_home: np.ndarray,
        home_move: np.ndarray,
    ) -> np.ndarray:
        """(A,) True where the override binds for the first A missions; ``moved`` (A, 2) then
        steps toward home instead (in place). ``flying_home``: (A,) the goal is home;
        ``home_move``: (A, 2) the step home where already computed, else NaN."""
        active = here.shape[0]
        step = self._step[:active]
        budget = (self._n_slots[:active] - slot - 1) * step + FEASIBILITY_SLACK_M
        bound, exact = self._bound[:active], self._exact[:active]
        overridden = np.zeros(active, bool)
        same_move = flying_home & ((moved[:, 0] != here[:, 0]) | (moved[:, 1] != here[:, 1]))
        check = np.flatnonzero(
            self.on[:active] & ~same_move & ~(bound + step < budget - BOUND_SLACK_M)
        )
        limit = budget[check]
        # the test is d_home(position) + step > budget; the straight line is a lower bound
        # on d_home, so well past the budget it holds without the exact distance
        sure = self._beeline(check, here[check]) + step[check] > limit + BOUND_SLACK_M
        now = exact[check]
        exact[:] = np.nan  # every UAV moves on
        unknown = np.isnan(now) & ~sure
        # then d_home(moved) > budget; the same lower bound decides most rows, the others
        # (speculatively, with the unknown d_home(position), in one query) need the distance
        back_sure = self._beeline(check, moved[check]) > limit + BOUND_SLACK_M
        ask = ~back_sure & (sure | unknown | (now + step[check] > limit))
        first, then = check[unknown], check[ask]
        found = self._distances(
            np.concatenate([first, then]), np.concatenate([here[first], moved[then]])
        )
        now[unknown] = found[: first.size]
        after = np.full(check.size, np.nan)
        after[ask] = found[first.size :]
        bound[check[~sure]] = now[~sure]
        near = sure | (now + step[check] > limit)
        back = near & (back_sure | (after > limit))
        keep = ask & ~back  # where the UAV ends this slot: the exact distance for the next one
        exact[check[keep]] = after[keep]
        rows = check[back]
        if rows.size:
            todo = rows[np.isnan(home_move[rows, 0])]
            if todo.size:
                home_move[todo] = self._nav.steps(
                    here[todo],
                    self._home[todo],
                    step[todo],
                    (self._sight[0][todo], self._sight[1][todo]),
                    checked=False,
                )
            moved[rows] = home_move[rows]
            overridden[rows] = True
        bound += step
        self._last[:] = False
        self._last[rows] = True
        return overridden
