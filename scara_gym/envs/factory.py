"""The vector entry point of the registered ids: the CPU or the CUDA vector env, one signature."""

from __future__ import annotations

from gymnasium.vector import VectorEnv

from scara_gym.envs.cuda_vector import ScaraCudaVectorEnv
from scara_gym.envs.vector import ScaraVectorEnv
from scara_gym.model import checks

DEVICES = ("cpu", "cuda")


def make_vector_env(num_envs: int = 1, device: str = "cpu", **kwargs) -> VectorEnv:
    """The vector entry point of the registered ids: ``device="cpu"`` (default) gives
    `ScaraVectorEnv`, ``device="cuda"`` the GPU backend
    (`scara_gym.envs.cuda_vector.ScaraCudaVectorEnv`), with the same arguments.
    """
    device = checks.choice("device", device, DEVICES)
    if device == "cuda":  # numba-cuda and torch are loaded when the env is made
        return ScaraCudaVectorEnv(num_envs=num_envs, **kwargs)
    return ScaraVectorEnv(num_envs=num_envs, **kwargs)
