"""Learning environments on the engine core (optional extra ``skymule[rl]``; needs gymnasium).

Importing this package registers ``skymule/DataMule-v0`` with Gymnasium::

    import gymnasium
    import skymule.envs  # registers the id

    env = gymnasium.make("skymule/DataMule-v0", scenario="paper-sim-autonomous")

(``gymnasium.make("skymule.envs:skymule/DataMule-v0", ...)`` imports it for you.)
:class:`skymule.envs.datamule.DataMuleEnv` is the class behind the id;
:class:`skymule.envs.vector.DataMuleVectorEnv` steps many missions at once.
"""

from __future__ import annotations

import gymnasium

ENV_ID = "skymule/DataMule-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="skymule.envs.datamule:DataMuleEnv")

__all__ = ["ENV_ID"]
