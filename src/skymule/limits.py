"""Physical limits on what a scenario, trace, volume file or rate table may say.

A number beyond these is a typo or a damaged file (``altitude_m = 1e300``, a 1e12 m/s UAV),
never a mission: it is refused in one line that names the limit, instead of flowing into the
engines as overflows, NaNs or a mission that silently serves nothing. The limits are generous
on purpose: skymule models small multirotors and large fixed-wing UAVs alike, so a legal or
typical figure is not the bound (FAA Part 107 caps small UAS at 400 ft, 122 m, above ground
level; that is context, not a limit here).
"""

from __future__ import annotations

import numpy as np

MAX_BUFFER_MBIT = 1e12
"""Largest sensor buffer or data volume [Mbit] (10^18 bit): sums over sensors and slots stay
far from overflow."""

MAX_DURATION_S = 1e7
"""Longest mission [s] (about 116 days): one row a slot must still fit in memory."""

MAX_COORDINATE_M = 1e7
"""Largest |x|, |y| in the local frame and |height| of an antenna [m] (the Earth's radius is
6.4e6 m)."""

MAX_ALTITUDE_M = 20_000.0
"""Highest flight altitude above the take-off point [m]: above the service ceiling of any UAV
(the RQ-4 Global Hawk's, the highest-flying in service, is about 18,300 m / 60,000 ft)."""

MAX_SPEED_MPS = 340.0
"""Fastest UAV speed [m/s]: the speed of sound at sea level (about 343 m/s); UAVs that ferry
data fly far below it (large fixed-wing ones cruise at 100-175 m/s)."""

MAX_EFFICIENCY_BPS_HZ = 100.0
"""Largest spectral efficiency a rate table may give [bit/s/Hz]: 1024-QAM carries 10 bit a
symbol, and Shannon's log2(1 + SNR) reaches 33 only at 100 dB SNR."""


MAX_BANDWIDTH_HZ = 1e11
"""Widest radio channel [Hz] (100 GHz): above any UAV link's (LTE's widest carrier is 20 MHz,
5G's 400 MHz, 802.11ay's 8.64 GHz); a wider figure is a typo (``1e308`` made every buffer
download in three slots)."""

MAX_SNR_DB = 300.0
"""Largest |SNR| [dB] a recorded trace may hold: 10^30 in power, far beyond any receiver
(with a 100 bit/s/Hz rate table, :data:`MAX_EFFICIENCY_BPS_HZ`, Shannon needs about 300 dB).
A sample of ``1e308`` is a damaged log, not a measurement."""


def at_most(limit: float, unit: str, why: str) -> str:
    """The words of a refusal: ``at most 340 m/s (the speed of sound ...)``."""
    return f"at most {limit:g} {unit} ({why})"


SPEED_LIMIT = at_most(MAX_SPEED_MPS, "m/s", "about the speed of sound; skymule's limit")
ALTITUDE_LIMIT = at_most(
    MAX_ALTITUDE_M, "m", "above any UAV's ceiling; skymule's limit above take-off"
)
COORDINATE_LIMIT = at_most(MAX_COORDINATE_M, "m", "the Earth's radius is 6.4e6 m")
BUFFER_LIMIT = at_most(MAX_BUFFER_MBIT, "Mbit", "skymule's largest buffer")


def waypoint_problem(points: np.ndarray) -> str | None:
    """What is wrong with (N, 3) waypoints ``[x_m, y_m, z_m]``, or None: finite, |x| and |y|
    within :data:`MAX_COORDINATE_M`, z (above take-off) from 0 to :data:`MAX_ALTITUDE_M`.

    Checked over the whole array at once; the first bad waypoint (and, in it, the first bad of
    x, y, z) is the one named."""
    xyz = np.asarray(points, float).reshape(-1, 3)
    with np.errstate(invalid="ignore"):
        bad = np.column_stack(
            (
                ~(np.abs(xyz[:, :2]) <= MAX_COORDINATE_M),  # NaN compares False: bad too
                ~((xyz[:, 2] >= 0) & (xyz[:, 2] <= MAX_ALTITUDE_M)),
            )
        )
    if not bad.any():
        return None
    index, axis = divmod(int(np.argmax(bad.ravel())), 3)
    value = float(xyz[index, axis])
    if axis < 2:
        return f"waypoint {index + 1}: {('x_m', 'y_m')[axis]} = {value!r}: {COORDINATE_LIMIT}"
    return (
        f"waypoint {index + 1}: z_m = {value!r}: allowed: 0 (the take-off ground) to "
        f"{MAX_ALTITUDE_M:g} m (above any UAV's ceiling; skymule's limit)"
    )
