# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""The MPC's per-step solve time and outcomes on a condition's tuning episodes, for one
configuration (the experiments log, 2026-12-03).

    python lab/mpc_solve_times.py random-shifts 4 "{'horizon': 20}" [voltage|pd]

The configuration is a Python literal of ``MPCConfig`` fields (``ast.literal_eval``: no code runs);
the last argument the environment's control mode (default "voltage").
"""

import ast
import sys
import time

import numpy as np

from agents.policies.mpc import MPCConfig, MPCPolicy
from scara_gym.benchmark.protocol import tuning


def main(condition_name: str, episodes: int, config: dict, mode: str = "voltage") -> None:
    condition = tuning(condition_name, episodes)
    env = condition.make_env(mode)
    policy = MPCPolicy(env, MPCConfig(**config))
    outcomes, started = [], time.perf_counter()
    for seed in condition.seeds():
        policy.reset()
        obs, info = env.reset(seed=seed, options=condition.options(seed))
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            done = terminated or truncated
        outcomes.append((bool(info["is_success"]), bool(info["collision"]), info["time"]))
    ms = np.array(policy.solve_times) * 1e3
    print(f"{condition_name} {mode} {config}: success {sum(o[0] for o in outcomes)}/{len(outcomes)}, collisions "
          f"{sum(o[1] for o in outcomes)}, mean time {np.mean([o[2] for o in outcomes]):.4f} s | solve ms median "
          f"{np.median(ms):.1f}, p95 {np.percentile(ms, 95):.1f}, worst {ms.max():.1f}; not converged "
          f"{policy.failures}; wall {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), ast.literal_eval(sys.argv[3]) if len(sys.argv) > 3 else {}, *sys.argv[4:5])
