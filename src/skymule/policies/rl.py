"""Learned policies: ``rl:path/to/model.zip`` runs a trained stable-baselines3 model.

The model must have been trained on ``skymule/DataMule-v0`` with ``move="headings"`` and
``scaled=True`` (what ``benchmarks/train_ppo.py`` does): this policy builds exactly that
observation from the engine's :class:`Observation` and the :class:`MissionContext`
(:mod:`skymule.envs.observation`), asks the model for its deterministic action and turns it
back into an :class:`Action`. It runs wherever a policy name does (``--policy``, ``compare``,
sweeps). Needs the optional extra ``skymule[rl]`` (stable-baselines3 and CPU torch).

A stable-baselines3 zip is unpickled as it loads, which can run code: the model is loaded
only when the user trusts that file on the command line (``--trust-model PATH``,
:mod:`skymule.trust`); otherwise one line says why it was refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

import skymule.envs.observation as enc
from skymule.errors import SkymuleError
from skymule.policies.base import Action, MissionContext, Observation
from skymule.rules.home import time_left_s
from skymule.scenario import PolicySpec
from skymule.trust import check_trusted

PREFIX = "rl:"


def load_model(path: Path) -> Any:
    """The stable-baselines3 PPO model at ``path`` (SkymuleError when it cannot be loaded).

    Refused, before anything of the file is read, unless the user trusts ``path``
    (:func:`skymule.trust.check_trusted`).
    """
    if not path.is_file():
        raise SkymuleError(f"policy 'rl:{path}': no such model file")
    check_trusted(f"rl:{path}", path)
    try:
        from stable_baselines3 import PPO
    except ImportError:
        raise SkymuleError(
            f"policy 'rl:{path}' needs stable-baselines3 and torch: pip install torch==2.13.0 "
            "(the CPU build) then pip install 'skymule[rl]'"
        ) from None
    try:
        return PPO.load(str(path), device="cpu")
    except Exception as exc:  # a damaged or foreign zip: say which file, in one line
        lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
        reason = lines[0] if lines else type(exc).__name__
        raise SkymuleError(
            f"policy 'rl:{path}': not a stable-baselines3 PPO model ({reason:.200})"
        ) from None


class RLPolicy:
    """A trained model as a skymule policy (see the module docstring)."""

    def __init__(self, spec: PolicySpec | str) -> None:
        name = spec if isinstance(spec, str) else spec.name
        if not name.startswith(PREFIX) or len(name) == len(PREFIX):
            raise SkymuleError(f"policy.name = {name!r}: give rl:path/to/model.zip")
        path = Path(name[len(PREFIX) :])
        self.name = f"{PREFIX}{path.stem}"  # no slashes: compare writes one folder per name
        self.model = load_model(path)
        self._context: MissionContext | None = None

    def reset(self, context: MissionContext) -> None:
        n = len(context.sensor_names)
        nvec = getattr(self.model.action_space, "nvec", None)
        if nvec is None or list(nvec) != [n + 1, enc.N_HEADINGS]:
            raise SkymuleError(
                f"policy {self.name!r}: the model's actions are {self.model.action_space}; this "
                f"mission needs MultiDiscrete([{n + 1}, {enc.N_HEADINGS}]) ({n} sensors, headings)"
            )
        self._context = context
        self._scale = enc.scale_vector(n)
        anchors = context.hover_points_m if context.hover_points_m is not None else None
        self._anchors = (
            np.asarray(anchors, float) if anchors is not None else context.sensor_m[:, :2]
        )

    def act(self, observation: Observation) -> Action:
        context = self._context
        if context is None:
            raise SkymuleError(f"policy {self.name!r}: act() before reset()")
        time_left = time_left_s(context.n_slots, observation.slot, context.slot_s)
        vector = enc.encode(
            np.asarray(observation.position_m[:2], float)[None],
            np.array([time_left]),
            observation.snr_db[None],
            observation.rate_bps[None],
            observation.remaining_bit[None],
            self._anchors[None],
        )[0]
        action, _ = self.model.predict(vector / self._scale, deterministic=True)
        serve, heading = (int(v) for v in np.asarray(action).reshape(2))
        sensor = enc.serve_index(serve)
        chosen = None if sensor < 0 else sensor
        if context.mode != "autonomous":
            return Action(serve=chosen, hover=heading == 0)
        if heading == 0:
            return Action(serve=chosen)
        move = enc.heading_step_m(np.array([heading]), context.max_step_m)[0]
        goto = (
            float(observation.position_m[0] + move[0]),
            float(observation.position_m[1] + move[1]),
        )
        return Action(serve=chosen, goto_m=goto)
