"""The AADM challenge's numbers, as its controller and testbed use them (the score's rules are
``skymule.aadm.score``, the protocol ``skymule.aadm.protocol``). Kept apart so that
``skymule --help`` and ``skymule aadm --help`` import neither numpy nor pandas."""

from __future__ import annotations

from skymule.rules.defaults import AADM_WINDOW_S as AADM_WINDOW_S

#: The controller's channel bandwidth [Hz] and nominal poll length [s].
AADM_BANDWIDTH_HZ = 1.4e6
AADM_POLL_S = 1.0

#: SNR the controller uses for a tower whose SNR cannot be read [dB].
UNREADABLE_SNR_DB = 0.0

#: The controller shares the volumes (and starts t1) at the first poll above this height [m].
SHARE_ALTITUDE_M = 24.0

#: The testbed's ports: UAV polls, telemetry, tower k at FIRST_TOWER_PORT + k - 1; and where
#: ``skymule aadm towers`` takes telemetry (beside the controller's) by default.
UAV_PORT, TELEMETRY_PORT, FIRST_TOWER_PORT, TOWERS_TELEMETRY_PORT = 8005, 8006, 8001, 8007

#: Mean wall time between two polls on the testbed [s]: the recorded flight log has 330 polls
#: in 339.2 s (gaps up to 4.4 s); the controller answers at most one poll a second.
TESTBED_POLL_INTERVAL_S = 1.031
