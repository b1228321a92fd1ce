"""SB3's ``HerReplayBuffer`` keeping only the info entries the goal env's reward reads.

With ``copy_info_dict=True`` SB3 stores every step's info dict and deep-copies the sampled
ones on every gradient step, to pass them to ``compute_reward``. The goal env's step info
(ScaraEnv's, with the wrappers' and DummyVecEnv's additions: the terminal observation, the
episode record) made that copy the larger part of a SAC update: 47 of 79 ms per update in a
cProfile of `Scara-C11-Goal-v0` (docs/experiments.md). ``Scara-C11-Goal-v0``'s ``compute_reward``
reads ``info["cost"]`` only, so ``info_keys=("cost",)`` stores just that and the relabeled
rewards are the same.

A module of its own, importing SB3 at the top, so that pickled buffers (the snapshots of
agents.algorithms.sb3.training) find the class again.
"""

from __future__ import annotations

from collections.abc import Sequence

from scara_gym.extras import require

require("stable_baselines3")
from stable_baselines3 import HerReplayBuffer

from scara_gym.model.checks import UserError, UserKeyError


class KeptInfoHerReplayBuffer(HerReplayBuffer):
    """``HerReplayBuffer`` that stores, of each step's info, only ``info_keys`` (None: all, as SB3)."""

    def __init__(self, *args, info_keys: Sequence[str] | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.info_keys = None if info_keys is None else tuple(info_keys)
        if self.info_keys is not None and not self.copy_info_dict:
            raise UserError("info_keys: the buffer keeps infos only with copy_info_dict=True")

    def add(self, obs, next_obs, action, reward, done, infos) -> None:
        position = self.pos
        super().add(obs, next_obs, action, reward, done, infos)  # the timeouts read the full infos
        if self.copy_info_dict and self.info_keys is not None:
            missing = [key for info in infos for key in self.info_keys if key not in info]
            if missing:
                raise UserKeyError(f"info_keys: the step info has no {sorted(set(missing))}; it has {sorted(infos[0])}")
            self.infos[position] = [{key: info[key] for key in self.info_keys} for info in infos]
