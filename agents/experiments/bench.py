"""The agents' training benchmarks (``scara-agents bench``): end-to-end PPO steps/s (the single-file
PPO beside SB3's), the cost of a SAC + HER update with SB3's buffer and ours, and off-policy training
steps/s of SB3, sb3-contrib and sbx-rl side by side (``--offpolicy``; sb3-contrib and sbx-rl are
optional packages of the offpolicy extra: ``pip install "scara_gym[offpolicy]"``)."""

from __future__ import annotations

import importlib.util
import os
import tempfile
import time

from agents.algorithms.sb3 import training
from agents.algorithms.sb3.hyperparams import load_hyperparams
from agents.algorithms.sb3.libraries import XLA_ONE_THREAD
from agents.algorithms.torch_ppo import Config, train
from scara_gym.benchmark.bench import gpu_available
from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.extras import require


def bench_ppo(device: str = "cpu", num_envs: int = 16, num_steps: int = 128, total_timesteps: int = 32768,
              sb3: bool = True, minibatch_size: int = 64, env_id: str = ENV_ID) -> dict:
    """End-to-end training steps/s of the single-file PPO and, with sb3, of stable-baselines3's PPO
    with equal batch settings (num_envs x num_steps per rollout, minibatches of minibatch_size,
    10 epochs, the same env id and arguments, VecNormalize for SB3 as the torch PPO normalizes),
    each timed over its learning loop."""
    minibatches = max(1, num_envs * num_steps // minibatch_size)
    with tempfile.TemporaryDirectory() as out:
        config = Config(env_id=env_id, device=device, num_envs=num_envs, num_steps=num_steps, num_minibatches=minibatches,
                        update_epochs=10, total_timesteps=total_timesteps, checkpoint_every=10**9, out=out)
        figures = {"torch_ppo": train(config)["steps_per_second"]}
    if sb3:
        require("stable_baselines3")
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import VecNormalize

        from scara_gym.integrations.sb3 import SB3VecEnv

        env = VecNormalize(SB3VecEnv(num_envs=num_envs, env_id=config.env_id, num_threads=1),
                           gamma=config.gamma)
        model = PPO("MlpPolicy", env, n_steps=num_steps, batch_size=minibatch_size, n_epochs=10, seed=0,
                    device="cpu")
        started = time.perf_counter()
        model.learn(total_timesteps)
        figures["sb3_ppo"] = total_timesteps / (time.perf_counter() - started)
    return figures


def bench_her(updates: int = 1000, repeats: int = 2) -> list[tuple[str, float]]:
    """Milliseconds per SAC + HER update on Scara-C11-Goal-v0 (sac.yml's block) with SB3's buffer and
    agents.algorithms.sb3.her's, alternated, so that both see the same machine load."""
    require("torch")
    import torch


    torch.set_num_threads(1)
    rows = []
    for _ in range(repeats):
        for info_keys in (None, ["cost"]):
            hyper = load_hyperparams("sac", "Scara-C11-Goal-v0", "pd")
            hyper.update(learning_starts=400, replay_buffer_kwargs={**hyper["replay_buffer_kwargs"],
                                                                    "info_keys": info_keys})
            env, _ = training.make_envs("Scara-C11-Goal-v0", {"control_mode": "pd", **hyper["env_kwargs"]}, hyper, 0)
            model = training.algorithm_class("sac")("MultiInputPolicy", env, seed=0, device="cpu",
                                                    **training.algorithm_kwargs("sac", hyper, 3))
            model.learn(1500)  # past learning_starts, the buffer holding a few episodes
            start = time.perf_counter()
            model.learn(updates, reset_num_timesteps=False)
            label = "SB3's HerReplayBuffer (every info entry)" if info_keys is None else f"info_keys={info_keys}"
            rows.append((label, (time.perf_counter() - start) / updates * 1e3))
    return rows


OFFPOLICY_PACKAGES = {"sb3_contrib": "sb3-contrib", "sbx": "sbx-rl"}
"""module -> the package bench_offpolicy needs beside stable-baselines3"""
OFFPOLICY_NET = [128, 128]
"""the hidden layers of every off-policy trainer's actor and critics in bench_offpolicy (but CrossQ's defaults)"""


def offpolicy_missing() -> list[str]:
    """The packages of OFFPOLICY_PACKAGES that are not installed (bench_offpolicy needs none missing)."""
    return [package for module, package in OFFPOLICY_PACKAGES.items() if importlib.util.find_spec(module) is None]


def _offpolicy_trainers() -> dict:
    """label -> (algorithm class, policy_kwargs) of every trainer bench_offpolicy times."""
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + XLA_ONE_THREAD).strip()
    import sbx
    from sb3_contrib import TQC
    from stable_baselines3 import SAC, TD3

    net = {"net_arch": list(OFFPOLICY_NET)}
    return {"SB3 SAC": (SAC, net), "SB3 TD3": (TD3, net), "sb3-contrib TQC": (TQC, net),
            "sbx SAC": (sbx.SAC, net), "sbx TD3": (sbx.TD3, net), "sbx TQC": (sbx.TQC, net),
            "sbx CrossQ (defaults)": (sbx.CrossQ, {}), "sbx CrossQ (128x128)": (sbx.CrossQ, net)}


def bench_offpolicy(steps: int = 1000, rounds: int = 3, learning_starts: int = 100, batch_size: int = 256,
                    env_id: str = ENV_ID) -> dict[str, float]:
    """Off-policy training steps/s after ``learning_starts`` (one update per environment step) of
    SB3's SAC and TD3, sb3-contrib's TQC and sbx-rl's SAC, TD3, TQC and CrossQ (at its defaults: a
    1024x1024 critic, a 256x256 actor, and at OFFPOLICY_NET), each on its own ``env_id`` in "pd"
    mode, one env, OFFPOLICY_NET networks, the libraries' other defaults but one ``batch_size``,
    on one torch thread and one XLA thread. Every trainer first runs past learning_starts and its
    first updates (JAX compiles there), untimed; then ``rounds`` rounds of ``steps`` steps each,
    the trainers in turn within each round, so that the machine's load falls on all alike."""
    import gymnasium as gym
    import torch

    torch.set_num_threads(1)
    models = {}
    for label, (algorithm, policy_kwargs) in _offpolicy_trainers().items():
        env = gym.make(env_id, control_mode="pd")
        models[label] = algorithm("MlpPolicy", env, learning_starts=learning_starts, batch_size=batch_size,
                                  policy_kwargs=dict(policy_kwargs) or None, seed=0, device="cpu")  # a copy: SB3 adds to it
        models[label].learn(learning_starts + 200)  # warm-up: the buffer past learning_starts, JAX compiled
    seconds = dict.fromkeys(models, 0.0)
    for _ in range(rounds):
        for label, model in models.items():
            started = time.perf_counter()
            model.learn(steps, reset_num_timesteps=False)
            seconds[label] += time.perf_counter() - started
    return {label: rounds * steps / s for label, s in seconds.items()}


def offpolicy_report(figures: dict[str, float], steps: int, rounds: int, env_id: str = ENV_ID) -> str:
    """bench_offpolicy's figures as a Markdown table, with each trainer's ratio to SB3 SAC."""
    base = figures["SB3 SAC"]
    lines = [f"Off-policy training on the CPU ({env_id}, \"pd\" mode, one env, 1 torch thread / 1 XLA thread, "
             f"{'x'.join(map(str, OFFPOLICY_NET))} networks unless said, batch 256, one update per step, "
             f"{rounds} interleaved rounds of {steps} steps after learning_starts):", "",
             "| trainer | steps/s | ratio to SB3 SAC |", "|---|---|---|"]
    lines += [f"| {label} | {value:,.0f} | {value / base:.2f} |" for label, value in figures.items()]
    return "\n".join(lines)


def main(quick: bool = False, her: bool = False, gpu: bool = False, env_ids: tuple[str, ...] = (ENV_ID,),
         offpolicy: bool = False) -> str:
    """The benchmark's report: CPU PPO on each of ``env_ids`` in turn, in one sitting (and GPU PPO
    where a CUDA device is usable, HER, and the off-policy trainers: with ``offpolicy`` every trainer
    of the sitting runs on one torch thread)."""
    require("torch")
    import torch

    if offpolicy:
        torch.set_num_threads(1)
    lines = []
    for env_id in env_ids:
        figures = bench_ppo(total_timesteps=4096 if quick else 32768, env_id=env_id)
        lines.append(f"PPO training on the CPU ({torch.get_num_threads()} torch threads, 16 envs x 128 steps, "
                     f"minibatches of 64, 10 epochs, {env_id}): the single-file PPO "
                     f"{figures['torch_ppo']:,.0f} steps/s, stable-baselines3 PPO {figures['sb3_ppo']:,.0f} "
                     f"steps/s, ratio {figures['torch_ppo'] / figures['sb3_ppo']:.2f}")
        print(lines[-1], flush=True)
    if gpu:
        why_not = gpu_available()
        if why_not is not None:
            lines.append(f"PPO on the GPU: skipped: {why_not}")
        else:
            gpu_ppo = bench_ppo(device="cuda", num_envs=4096, num_steps=32,
                                total_timesteps=4096 * 32 * (2 if quick else 8), sb3=False,
                                minibatch_size=4096 * 32 // 4)
            lines.append(f"PPO on the GPU (4,096 envs x 32 steps, 4 minibatches, everything on the device): "
                         f"{gpu_ppo['torch_ppo']:,.0f} steps/s end to end")
        print(lines[-1], flush=True)
    if her:
        for label, ms in bench_her(200 if quick else 1000, 1 if quick else 2):
            lines.append(f"{label}: {ms:.1f} ms per SAC update")
            print(lines[-1], flush=True)
    if offpolicy:
        steps, rounds = (200, 2) if quick else (1000, 3)
        lines.append(offpolicy_report(bench_offpolicy(steps, rounds, env_id=env_ids[0]), steps, rounds, env_ids[0]))
        print(lines[-1], flush=True)
    return "\n".join(lines)
