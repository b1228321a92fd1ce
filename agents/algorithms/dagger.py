"""DAgger (Ross, Gordon and Bagnell, 2011): a network distilled from an expert at the states the
network itself visits, in one file.

The distillation of issue "A learned controller at the optimum's level": the expert is the
real-time MPC (``mpc-rti``, agents.policies.mpc_rti) by default, the network the behaviour
cloning's MLP (agents.algorithms.bc.Actor), and its outputs the residuals of
scara_gym.wrappers.residual (a set-point around the target in "pd" mode, or a correction of the PD
law's voltages in "voltage" mode): a plain regression of absolute set-points cannot settle inside
the 1e-3 rad band (agents.algorithms.bc says why). Each iteration i:

1. runs ``episodes_per_iteration`` training episodes, the conditions of the config in turn, each from
   its own seed (`DAGGER_SEED`) with the condition's drawn start or corner; at every step the expert
   labels the state and the step's action is the expert's with probability beta^i, else the
   network's (iteration 0 is the expert alone: behaviour cloning's data);
2. adds every (observation, label) to the aggregate and trains the network on all of it for
   ``steps_per_iteration`` Adam steps, continuing its weights;
3. scores the network alone on the tuning set of each condition (scara_gym.benchmark.protocol.tuning:
   never an evaluation seed): the *tuning gap* is its mean time to the C11 band, an episode that
   fails or collides counting the time limit, minus the expert's on the same episodes.

It stops after ``iterations``, or once the gap has not shrunk for ``patience`` iterations; the run
keeps the weights of the iteration with the smallest gap (picked on the tuning sets alone). The
expert acts every step, also when the network's action is applied: the real-time MPC's plan is
warm-started from its own last step and follows the state it is given.

A run folder holds model.pt and config.json as a behaviour-cloning run does (``bc:DIR`` loads its
policy, agents.algorithms.bc.BCPolicy), summary.json with every iteration's figures, and
checkpoint.pt (the aggregate, the weights, the generators) after each iteration: an interrupted run
resumes at the next iteration with the same result as an uninterrupted one.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from scara_gym.extras import require

require("torch")
import torch

from agents.algorithms.bc import Actor, ActorPolicy, fit, residual_outputs
from agents.algorithms.dagger_config import DAGGER_SEED, DAggerConfig
from agents.algorithms.loaders import load_policy
from agents.files import (
    POLICY_FILES,
    claim_run_folder,
    exclusive,
    json_record,
    load_torch,
    save_torch,
    write_digests,
    write_json,
)
from scara_gym.benchmark.protocol import evaluate, get_condition, tuning
from scara_gym.wrappers import ResidualSetpoint, residual_setpoint

TIME_LIMIT = 3.0
"""[s] what a failed or colliding episode counts in the tuning gap (the episode's length)"""


def run_record(config: DAggerConfig) -> dict:
    """What a run of ``config`` is, for agents.files.claim_run_folder."""
    settings = {k: v for k, v in config.to_dict().items() if k not in ("out", "torch_threads")}
    return {"trainer": "dagger", "algo": "dagger", "env_id": config.env_id, "control_mode": config.control_mode,
            "seed": config.seed, "settings": settings}


def labels(mapping, obs: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """The network's targets for the expert's env ``actions``: their residual outputs under
    ``mapping`` (none: the actions themselves)."""
    if mapping is None:
        return actions.astype(np.float32)
    if isinstance(mapping, ResidualSetpoint):
        return residual_outputs(mapping, obs, actions)
    return mapping.agent_actions(obs, actions).astype(np.float32)


def learner_map(env, config: DAggerConfig):
    """The residual map of ``config`` on ``env`` (None: the network acts in the env's own actions)."""
    return residual_setpoint(env.unwrapped, config.residual_scale, config.residual_deadzone, config.residual_on)


def collect(config: DAggerConfig, iteration: int, envs: dict, experts: dict, actor: Actor,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, dict]:
    """One iteration's episodes: (observations, labels, figures)."""
    beta = config.beta ** iteration
    observations, targets, successes, expert_steps, steps = [], [], [], 0, 0
    for k in range(config.episodes_per_iteration):
        name = config.conditions[k % len(config.conditions)]
        condition, env, expert = get_condition(name), envs[name], experts[name]
        learner = ActorPolicy(actor, learner_map(env, config), "dagger")
        seed = DAGGER_SEED + config.seed * 10**5 + iteration * 10**3 + k
        obs, _ = env.reset(seed=seed, options=condition.options(seed))
        expert.reset()
        episode_obs, episode_actions = [], []
        while True:
            label = np.asarray(expert(obs), dtype=np.float64)
            episode_obs.append(np.asarray(obs, dtype=np.float32))
            episode_actions.append(label)
            by_expert = bool(rng.random() < beta)
            expert_steps += by_expert
            steps += 1
            obs, _, terminated, truncated, info = env.step(label if by_expert else learner(obs))
            if terminated or truncated:
                successes.append(bool(info["is_success"]))
                break
        episode_obs = np.array(episode_obs)
        observations.append(episode_obs)
        targets.append(labels(learner.mapping, episode_obs, np.array(episode_actions)))
    return np.concatenate(observations), np.concatenate(targets), {
        "episodes": config.episodes_per_iteration, "steps": steps, "expert_share": expert_steps / steps,
        "success_rate": float(np.mean(successes)), "beta": beta}


def tuning_time(policy_factory, config: DAggerConfig) -> dict:
    """Mean time to the C11 band over each condition's tuning episodes, a failed or colliding one
    counting TIME_LIMIT; and its success and collision rates."""
    times, success, collisions = [], [], []
    for name in config.conditions:
        result = evaluate(tuning(name, config.tuning_episodes), policy_factory, config.control_mode,
                          env_id=config.env_id, record=0)
        clean = result["success"] & ~result["collisions"]
        times.append(np.where(clean, result["reach_time"], TIME_LIMIT))
        success.append(result["success"])
        collisions.append(result["collisions"] > 0)
    return {"mean_time": float(np.concatenate(times).mean()), "success_rate": float(np.concatenate(success).mean()),
            "collision_rate": float(np.concatenate(collisions).mean())}


def train(config: DAggerConfig, overwrite: bool = False, resume: bool = False) -> dict:
    """Train and write the run folder (module docstring); returns its record (config.json)."""
    out = Path(config.out)
    started = time.perf_counter()
    with exclusive(out):
        claim_run_folder(out, run_record(config), resume, overwrite)
        if resume and (out / "model.pt").exists() and (out / "summary.json").exists():
            return json_record(out / "config.json")
        if config.torch_threads:
            torch.set_num_threads(config.torch_threads)
        envs = {name: get_condition(name).make_env(config.control_mode, config.env_id) for name in config.conditions}
        experts = {name: load_policy(config.expert, env) for name, env in envs.items()}
        first = next(iter(envs.values()))
        obs_size, action_size = first.observation_space.shape[0], first.action_space.shape[0]
        torch.manual_seed(config.seed)
        actor = Actor(obs_size, action_size, config.hidden_size, config.layers)
        optimizer = torch.optim.Adam(actor.parameters(), lr=config.learning_rate)
        generator = torch.Generator().manual_seed(config.seed)
        rng = np.random.default_rng((config.seed, 0xDA66E5))
        obs = np.zeros((0, obs_size), np.float32)
        targets = np.zeros((0, action_size), np.float32)
        history, best, iteration = [], None, 0
        expert_tuning = None
        if resume and (out / "checkpoint.pt").exists():
            saved = load_torch(out / "checkpoint.pt")
            actor.load_state_dict(saved["actor"])
            optimizer.load_state_dict(saved["optimizer"])
            generator.set_state(saved["generator"])
            rng.bit_generator.state = json_state(saved["rng"])
            obs, targets = saved["obs"].numpy(), saved["targets"].numpy()
            history, best, iteration = saved["history"], saved["best"], saved["iteration"]
            expert_tuning = saved["expert_tuning"]
        if expert_tuning is None:
            expert_tuning = tuning_time(lambda env: load_policy(config.expert, env), config)
        # the patience is in the loop's condition: a run resumed after it ran out ends at once
        while iteration < config.iterations and (best is None or iteration - best["iteration"] <= config.patience):
            new_obs, new_targets, figures = collect(config, iteration, envs, experts, actor, rng)
            obs, targets = np.concatenate([obs, new_obs]), np.concatenate([targets, new_targets])
            if iteration == 0:  # the standardization: the expert's own states
                actor.mean.copy_(torch.as_tensor(obs.mean(0)))
                actor.scale.copy_(torch.as_tensor(obs.std(0) + 1e-6))
            loss = fit(actor, optimizer, obs, targets, config.steps_per_iteration, config.batch_size, generator)
            actor.eval()
            scored = tuning_time(lambda env: ActorPolicy(actor, learner_map(env, config), "dagger"), config)
            actor.train()
            gap = scored["mean_time"] - expert_tuning["mean_time"]
            history.append({"iteration": iteration, **figures, "transitions": len(obs), "loss": loss,
                            "tuning": scored, "gap": gap})
            print(f"dagger iteration {iteration}: {len(obs):,} transitions, loss {loss:.4g}, tuning success "
                  f"{scored['success_rate']:.2f}, collisions {scored['collision_rate']:.2f}, gap {gap:+.4f} s "
                  f"({time.perf_counter() - started:.0f} s)", flush=True)
            if best is None or gap < best["gap"]:
                best = {"iteration": iteration, "gap": gap, "state_dict": {k: v.clone() for k, v in
                                                                            actor.state_dict().items()}}
            iteration += 1
            save_torch({"actor": actor.state_dict(), "optimizer": optimizer.state_dict(),
                        "generator": generator.get_state(), "rng": state_json(rng.bit_generator.state),
                        "obs": torch.as_tensor(obs), "targets": torch.as_tensor(targets), "history": history,
                        "best": best, "iteration": iteration, "expert_tuning": expert_tuning}, out / "checkpoint.pt")
        save_torch({"state_dict": best["state_dict"], "obs_size": obs_size, "action_size": action_size,
                    "hidden_size": config.hidden_size, "layers": config.layers}, out / "model.pt")
        summary = {"train_seconds": time.perf_counter() - started, "iterations": history,
                   "best_iteration": best["iteration"], "expert_tuning": expert_tuning,
                   "rule": "the iteration with the smallest tuning gap (mean time to the C11 band on the "
                           "conditions' tuning sets, failures and collisions at the time limit, minus the expert's)"}
        write_json(out / "summary.json", summary)
        record = {**config.to_dict(), "algo": "dagger", "trainer": "dagger", "transitions": len(obs),
                  "best_iteration": best["iteration"], "train_seconds": summary["train_seconds"]}
        write_json(out / "config.json", record)
        write_digests(out, POLICY_FILES)
    return record


def state_json(state: dict) -> dict:
    """numpy's generator state with its big integers as text (torch's weights-only loader keeps
    ints within 64 bits)."""
    inner = state["state"]
    return {**state, "state": {k: str(v) for k, v in inner.items()}}


def json_state(state: dict) -> dict:
    return {**state, "state": {k: int(v) for k, v in state["state"].items()}}
