"""Defaults every component shares, each stated once (plain floats: no numpy imported)."""

from __future__ import annotations

#: HGAD's longest hover [s] (``[policy.params] max_hover_s``).
MAX_HOVER_S = 60.0

#: HGAD's hover trigger, as a fraction of each sensor's peak rate (``hover_threshold``).
HOVER_THRESHOLD = 1.0

#: The AADM challenge's download window since the volumes were shared [s]
#: (``[mission] aadm_window_s`` when unset).
AADM_WINDOW_S = 500.0
