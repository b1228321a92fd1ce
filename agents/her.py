"""SB3's ``HerReplayBuffer`` keeping only the info entries the goal env's reward reads.

With ``copy_info_dict=True`` SB3 stores every step's info dict and deep-copies the sampled
ones on every gradient step, to pass them to ``compute_reward``. The goal env's step info
(ScaraEnv's, with the wrappers' and DummyVecEnv's additions: the terminal observation, the
episode record) made that copy the larger part of a SAC update: 47 of 79 ms per update in a
cProfile of `Scara-C11-Goal-v0` (2026-11-29). ``Scara-C11-Goal-v0``'s ``compute_reward``
reads ``info["cost"]`` only, so ``info_keys=("cost",)`` stores just that and the relabeled
rewards are the same.

A module of its own, importing SB3 at the top, so that pickled buffers (the snapshots of
agents.training) find the class again.
"""

from __future__ import annotations

from collections.abc import Sequence

from stable_baselines3 import HerReplayBuffer


class KeptInfoHerReplayBuffer(HerReplayBuffer):
    """``HerReplayBuffer`` that stores, of each step's info, only ``info_keys`` (None: all, as SB3)."""

    def __init__(self, *args, info_keys: Sequence[str] | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.info_keys = None if info_keys is None else tuple(info_keys)
        if self.info_keys is not None and not self.copy_info_dict:
            raise ValueError("info_keys: the buffer keeps infos only with copy_info_dict=True")

    def add(self, obs, next_obs, action, reward, done, infos) -> None:
        position = self.pos
        super().add(obs, next_obs, action, reward, done, infos)  # the timeouts read the full infos
        if self.copy_info_dict and self.info_keys is not None:
            missing = [key for info in infos for key in self.info_keys if key not in info]
            if missing:
                raise KeyError(f"info_keys: the step info has no {sorted(set(missing))}; it has {sorted(infos[0])}")
            self.infos[position] = [{key: info[key] for key in self.info_keys} for info in infos]


def main(argv: list[str] | None = None) -> None:
    """``python -m agents.her``: milliseconds per SAC + HER update on Scara-C11-Goal-v0 (sac.yml's
    block) with SB3's buffer and this one, alternated, so that both see the same machine load."""
    import argparse
    import time

    import torch

    from agents import training

    parser = argparse.ArgumentParser(description=main.__doc__.split("\n\n")[0])
    parser.add_argument("--updates", type=int, default=1000, help="timed SAC steps per measurement")
    parser.add_argument("--repeats", type=int, default=2, help="measurements per buffer")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    for _ in range(args.repeats):
        for info_keys in (None, ["cost"]):
            hyper = training.load_hyperparams("sac", "Scara-C11-Goal-v0", "pd")
            hyper.update(learning_starts=400, replay_buffer_kwargs={**hyper["replay_buffer_kwargs"],
                                                                    "info_keys": info_keys})
            env, _ = training.make_envs("Scara-C11-Goal-v0", {"control_mode": "pd", **hyper["env_kwargs"]}, hyper, 0)
            model = training.algorithm_class("sac")("MultiInputPolicy", env, seed=0, device="cpu",
                                                    **training.algorithm_kwargs("sac", hyper, 3))
            model.learn(1500)  # past learning_starts, the buffer holding a few episodes
            start = time.perf_counter()
            model.learn(args.updates, reset_num_timesteps=False)
            label = "SB3's HerReplayBuffer (every info entry)" if info_keys is None else f"info_keys={info_keys}"
            print(f"{label}: {(time.perf_counter() - start) / args.updates * 1e3:.1f} ms per SAC update", flush=True)


if __name__ == "__main__":
    main()
