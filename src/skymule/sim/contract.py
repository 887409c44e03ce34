"""Moved to :mod:`skymule.rules.contract` (the rules layer); kept as a re-export so code that
still imports ``skymule.sim.contract`` (``aadm/score.py``) keeps working until it moves too."""

from skymule.rules.contract import *  # noqa: F403
from skymule.rules.contract import served_bits, window_slots  # noqa: F401
