"""What happened, and what it amounts to.

* :mod:`~skymule.metrics.flights`: the run record (``Flights``: B flights; ``MissionLog``: one);
* :mod:`~skymule.metrics.visits`: the order in which sensors were visited;
* :mod:`~skymule.metrics.summary`: the record's ``summary.json`` figures, for one mission or many;
* :mod:`~skymule.metrics.sim2real`: how far a twin's numbers are from a real flight's, with
  block-bootstrap intervals (``skymule sim2real``).
"""
