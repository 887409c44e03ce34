"""The AADM challenge's numbers, as its controller uses them (``skymule.aadm.score`` has the
rules that use them). Kept apart from the score so that ``skymule aadm --help`` imports no
numpy."""

from __future__ import annotations

#: The challenge's download window since the volumes were shared [s].
AADM_WINDOW_S = 500.0

#: The controller's channel bandwidth [Hz] and nominal poll length [s].
AADM_BANDWIDTH_HZ = 1.4e6
AADM_POLL_S = 1.0

#: SNR the controller uses for a tower whose SNR cannot be read [dB].
UNREADABLE_SNR_DB = 0.0

#: The controller shares the volumes (and starts t1) at the first poll above this height [m].
SHARE_ALTITUDE_M = 24.0
