# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""Where the speed targets of "The exact environment at full speed" meet the accuracy targets (the
experiments log, 2026-12-03, "the speed targets against the accuracy targets").

Prints, in one sitting on this machine:
1. `scara-c11 accuracy`'s worst errors at v2's rtol 1e-7 / atol 1e-9, unweighted and with
   tolerance_weights {"q": 0.03, "current": 30}, on the tuning seeds 0-5 (where the weights were
   chosen) and on the held-out seeds 6-11, 200 episodes per seed;
2. integration steps per control step of random "pd" actions, in control steps without a mode
   switch and in those with one, for v0, v2 and v2 with the weights;
3. the compiled step's time for the same ids, and for v2 with the weights and switches seen at step
   ends only (exact_switches=False): a stand-in for a switch search that costs nothing;
4. the native vector env's robot-steps/s at N = 4,096 ("pd", random actions);
5. the single-file PPO's training steps/s on v1 and v2 (16 envs x 128 steps, minibatches of 64,
   10 epochs, 8,192 steps) and the time its 16-env vector env takes for one rollout.

    PYTHONPATH=. python lab/speed_floor.py [--skip-accuracy] [--skip-ppo]

About 10 minutes on 2 cores (accuracy about 4, PPO about 2).
"""

from __future__ import annotations

import argparse
import tempfile
import time

import gymnasium as gym
import numpy as np

import scara_gym  # noqa: F401  (registers the ids)
from scara_gym.benchmark.accuracy import TARGETS, run, summary
from scara_gym.benchmark.bench import fastest_compiled_runs
from scara_gym.envs.core import step_robot

WEIGHTS = {"q": 0.03, "current": 30}
CANDIDATES = {  # label -> (id, extra constructor arguments)
    "v0": ("Scara-C11-v0", {}),
    "v2": ("Scara-C11-v2", {}),
    "v2 + weights": ("Scara-C11-v2", {"tolerance_weights": WEIGHTS}),
}


def accuracy_rows() -> None:
    print("1. accuracy at rtol 1e-7 / atol 1e-9, 200 episodes per seed (worst error / target; episodes over)")
    for label, weights in (("unweighted (v2)", None), (f"weights {WEIGHTS}", WEIGHTS)):
        for seeds in ((0, 1, 2, 3, 4, 5), (6, 7, 8, 9, 10, 11)):
            rows = [row for seed in seeds for row in run(200, seed, 1e-7, 1e-9, True, weights)]
            worst = summary(rows)
            ratios = ", ".join(f"{name} {worst[name]:.2e} ({worst[name] / target:.2f})" for name, target in TARGETS.items())
            over = {name: episodes for name, episodes in worst["over_target"].items() if episodes}
            print(f"   {label}, seeds {seeds[0]}-{seeds[-1]}: {ratios}; over: {over or 'none'}; "
                  f"RHS per control step {worst['rhs_per_step']:.1f}", flush=True)


def step_counts(steps: int = 3000) -> None:
    print(f"2. integration steps (rejected included) per control step, {steps} random 'pd' actions, seed 0")
    for label, (env_id, kwargs) in CANDIDATES.items():
        env = gym.make(env_id, control_mode="pd", **kwargs)
        task = env.unwrapped._task
        arrays = (task.robots, task.robot_params, task.step_config, task.constants, task.log, task.outcomes, task.obs)
        robot, outcome = task.robots[0], task.outcomes[0]
        env.reset(seed=0)
        env.action_space.seed(0)
        quiet, switching = [], []
        for _ in range(steps):
            action = np.asarray(env.action_space.sample(), dtype=np.float64)
            before = robot["n_steps"] + robot["n_rejected"]
            step_robot(0, action, *arrays)
            (quiet if robot["n_events"] == 0 else switching).append(robot["n_steps"] + robot["n_rejected"] - before)
            if outcome["reached"] or outcome["episode_steps"] >= env.spec.max_episode_steps:
                env.reset()
        print(f"   {label}: {np.mean(quiet):.1f} in the {len(quiet)} control steps without a switch, "
              f"{np.mean(switching):.1f} in the {len(switching)} with one", flush=True)


def compiled_times(steps: int = 1500, rounds: int = 5) -> None:
    print(f"3. compiled step [us per control step], best of {rounds} passes over {steps} random 'pd' actions")
    candidates = dict(CANDIDATES)
    candidates["v2 + weights, switches at step ends"] = ("Scara-C11-v2",
                                                         {"tolerance_weights": WEIGHTS, "exact_switches": False})
    envs = {label: gym.make(env_id, control_mode="pd", **kwargs) for label, (env_id, kwargs) in candidates.items()}
    best = fastest_compiled_runs(envs, steps, rounds)
    v0 = best["v0"]["untimed"]
    for label, result in best.items():
        print(f"   {label}: {result['untimed'] / steps * 1e6:.2f} us ({v0 / result['untimed']:.2f}x v0's speed), "
              f"{result['rhs'] / steps:.1f} RHS and {result['steps'] / steps:.1f} integration steps per control step")


def vector_rates(n: int = 4096, steps: int = 20, rounds: int = 2) -> None:
    print(f"4. native vector env, N = {n}, 'pd', random actions, best of {rounds} x {steps} steps")
    venvs = {label: gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", control_mode="pd",
                                 collision="penalty", **kwargs) for label, (env_id, kwargs) in CANDIDATES.items()}
    best = dict.fromkeys(venvs, 0.0)
    for _ in range(rounds):
        for label, venv in venvs.items():
            venv.reset(seed=0)
            venv.action_space.seed(0)
            actions = [venv.action_space.sample() for _ in range(steps)]
            venv.step(actions[0])
            started = time.perf_counter()
            for action in actions:
                venv.step(action)
            best[label] = max(best[label], n * steps / (time.perf_counter() - started))
    for label, rate in best.items():
        print(f"   {label}: {rate:,.0f} robot-steps/s ({rate / best['v0']:.2f}x v0)")


def ppo_rates() -> None:
    from agents.algorithms.torch_ppo import Config, train

    print("5. single-file PPO, 16 envs x 128 steps, minibatches of 64, 10 epochs, 8,192 steps (best of 2)")
    for env_id in ("Scara-C11-v1", "Scara-C11-v2"):
        rates = []
        for _ in range(2):
            with tempfile.TemporaryDirectory() as out:
                config = Config(env_id=env_id, num_envs=16, num_steps=128, num_minibatches=32, update_epochs=10,
                                total_timesteps=8192, checkpoint_every=10**9, out=out)
                rates.append(train(config)["steps_per_second"])
        venv = gym.make_vec(env_id, num_envs=16, vectorization_mode="vector_entry_point", num_threads=1)
        venv.reset(seed=0)
        venv.action_space.seed(0)
        actions = [venv.action_space.sample() for _ in range(128)]
        started = time.perf_counter()
        for action in actions:
            venv.step(action)
        rollout = time.perf_counter() - started
        iteration = 16 * 128 / max(rates)
        print(f"   {env_id}: {max(rates):,.0f} steps/s; the env's 16 x 128 steps take {rollout * 1e3:.0f} ms of each "
              f"{iteration * 1e3:.0f} ms iteration ({rollout / iteration:.0%})", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-accuracy", action="store_true")
    parser.add_argument("--skip-ppo", action="store_true")
    args = parser.parse_args()
    # v0 and v1 are measured on purpose: Gymnasium says once each that they are out of date
    if not args.skip_accuracy:
        accuracy_rows()
    step_counts()
    compiled_times()
    vector_rates()
    if not args.skip_ppo:
        ppo_rates()


if __name__ == "__main__":
    main()
