"""The agents' training benchmarks (``scara-agents bench``): end-to-end PPO steps/s (the single-file
PPO beside SB3's) and the cost of a SAC + HER update with SB3's buffer and ours."""

from __future__ import annotations

import tempfile
import time

from agents.algorithms.sb3 import training
from agents.algorithms.sb3.hyperparams import load_hyperparams
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


def main(quick: bool = False, her: bool = False, gpu: bool = False, env_ids: tuple[str, ...] = (ENV_ID,)) -> str:
    """The benchmark's report: CPU PPO on each of ``env_ids`` in turn, in one sitting (and GPU PPO
    where a CUDA device is usable, and HER)."""
    require("torch")
    import torch

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
    return "\n".join(lines)
