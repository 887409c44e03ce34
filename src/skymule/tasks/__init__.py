"""What a user does with skymule, each a library call the CLI wraps.

* :mod:`~skymule.tasks.simulate`: one scenario, one run (``simulate``, ``skymule run``);
* :mod:`~skymule.tasks.fleet`: the same for several UAVs;
* :mod:`~skymule.tasks.compare`: policies or signal sources on identical draws, with the bound;
* :mod:`~skymule.tasks.analyze`: replay of recorded AADM flights;
* :mod:`~skymule.tasks.resilience`: degradation curves over a fault's intensity;
* :mod:`~skymule.tasks.radiomaps`: fit and score radio maps.
"""
