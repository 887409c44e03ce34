"""Training the ``learned`` policy: the missions it trains on (:mod:`.missions`), evolution
strategies on the engine (:mod:`.es`, numpy only) and the PPO comparison (:mod:`.ppo`, needs
the ``rl`` extra's torch). The trained model itself runs without any of this
(:mod:`skymule.policies.learned`)."""
