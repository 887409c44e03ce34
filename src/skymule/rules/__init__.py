"""The rules layer: what every engine, policy, planner, bound, environment and the AADM
controller obeys, each rule written once. It imports nothing from skymule above it.

* :mod:`~skymule.rules.defaults` -- the defaults (HGAD's hover, the AADM window), stated once;
* :mod:`~skymule.rules.contract` -- the slot contract (``docs/contract.md``): served bits
  y = min(R dt, Q), the download window and slot arithmetic (one form, one epsilon), the
  choices (Greedy, HGAD, HGAD's hover state), fleet conflicts;
* :mod:`~skymule.rules.home` -- time left and the return-home deadline;
* :mod:`~skymule.rules.score` -- the AADM score and its per-slot reward.

Importing this package loads nothing (``defaults`` needs no numpy either).
"""
