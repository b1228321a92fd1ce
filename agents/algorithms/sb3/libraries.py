"""The libraries a run's block may train with, all behind stable-baselines3's interfaces.

A block's ``library`` (default ``"sb3"``) picks the implementation of its algorithm:

| library | package | algorithms |
|---|---|---|
| ``sb3`` | stable-baselines3 | ppo, sac, td3 |
| ``sb3-contrib`` | sb3-contrib | tqc |
| ``sbx`` | sbx-rl (JAX) | ppo, sac, td3, tqc, crossq |

They share SB3's model API (``learn``, ``save``, ``load``, ``predict``, callbacks, VecNormalize,
replay buffers), so training, snapshots, checkpoints and evaluation are one code path. Why sbx:
its off-policy steps are about twice SB3's on these 2-core machines (issue 58's side-by-side
figures; ``scara-agents bench --offpolicy`` measures them again), and off-policy budgets are the
scarce resource here.

JAX's CPU backend spreads one small network's work over every core; like torch's threads (one
per run, agents.algorithms.sb3.training.DEFAULT_TORCH_THREADS) it is held to one thread, which is
faster here when runs share the cores, and set before JAX is imported.
"""

from __future__ import annotations

import os

from scara_gym.extras import require
from scara_gym.model.checks import UserError

LIBRARIES = {
    "sb3": ("stable_baselines3", ("ppo", "sac", "td3")),
    "sb3-contrib": ("sb3_contrib", ("tqc",)),
    "sbx": ("sbx", ("ppo", "sac", "td3", "tqc", "crossq")),
}
"""library -> (its module, the algorithms it trains here)"""
OFF_POLICY = ("sac", "td3", "tqc", "crossq")
"""the algorithms with a replay buffer"""
XLA_ONE_THREAD = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
"""XLA_FLAGS that keep JAX's CPU backend on one thread, set before sbx imports JAX"""
CLASS_NAMES = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "tqc": "TQC", "crossq": "CrossQ"}


def check_library(algo: str, library: str) -> None:
    """A user's mistake in a block's library or algorithm, named with what is allowed."""
    if library not in LIBRARIES:
        raise UserError(f"library must be one of {sorted(LIBRARIES)}, got {library!r}")
    if algo not in LIBRARIES[library][1]:
        raise UserError(f"library {library!r} trains {list(LIBRARIES[library][1])} here, not {algo!r}")


def algorithm_class(algo: str, library: str = "sb3"):
    """The class that trains and loads ``algo`` in ``library`` (LIBRARIES)."""
    check_library(algo, library)
    module_name = LIBRARIES[library][0]
    if library == "sbx":  # before JAX is imported: one CPU thread, no accelerator probing
        os.environ.setdefault("JAX_PLATFORMS", "cpu")
        if XLA_ONE_THREAD not in os.environ.get("XLA_FLAGS", ""):
            os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + XLA_ONE_THREAD).strip()
    require(module_name)
    import importlib

    return getattr(importlib.import_module(module_name), CLASS_NAMES[algo])
