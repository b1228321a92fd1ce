"""Checkpoint selection (``scara-agents select RUN --out models/NAME``): ship the best checkpoint of a run.

PPO on this task is not monotone: the fastest policies can appear mid-run and the final
one can be slower. ``scara-agents train ppo-residual`` saves a checkpoint about every 100k steps together with
its VecNormalize statistics; this evaluates each one over the same seeds and copies the
fastest checkpoint that succeeds in every episode without a collision (as EvalCallback's
best model, but with the matching normalization statistics) to OUT, with its evaluation
log and a config.json that records the selection.
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

import gymnasium as gym

from agents.algorithms.sb3.policy import PPOPolicy
from agents.files import POLICY_FILES, record_trusted, require_trusted, write_digests, write_json
from agents.policies import run_episode


def evaluate_checkpoints(run: Path, episodes: int = 5, seed: int = 5000) -> list[dict]:
    config = json.loads((run / "config.json").read_text())
    kwargs = {k: config["env_kwargs"][k] for k in ("control_mode", "randomize_target")}
    env = gym.make(config.get("env_id", "Scara-C11-v0"), **kwargs)
    rows = []
    require_trusted(run / "checkpoints")  # pickle: the run's own manifest, trusted, before any is staged
    checkpoints = sorted(run.glob("checkpoints/ppo_[0-9]*_steps.zip"), key=lambda p: int(p.stem.split("_")[1]))
    with tempfile.TemporaryDirectory() as scratch:
        for checkpoint in checkpoints:
            steps = int(checkpoint.stem.split("_")[1])
            model_dir = Path(scratch) / str(steps)
            stage(run, steps, model_dir)
            policy = PPOPolicy(env, model_dir, trust=True)  # a staged copy of the checked files
            results = [run_episode(env, policy, seed=seed + i) for i in range(episodes)]
            times = [r["reach_time"] for r in results if r["success"]]
            rows.append({"steps": steps, "success_rate": len(times) / episodes,
                         "collision_rate": sum(r["collisions"] > 0 for r in results) / episodes,
                         "mean_time": sum(times) / len(times) if times else math.nan})
            print(rows[-1], flush=True)
    return rows


def stage(run: Path, steps: int, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    shutil.copy(run / "checkpoints" / f"ppo_{steps}_steps.zip", out / "model.zip")
    shutil.copy(run / "checkpoints" / f"ppo_vecnormalize_{steps}_steps.pkl", out / "vecnormalize.pkl")
    shutil.copy(run / "config.json", out / "config.json")


def select_checkpoint(run: Path, out: Path, episodes: int = 5, seed: int = 5000) -> dict:
    """Evaluate every checkpoint of ``run`` and ship the fastest that succeeds in every episode
    without a collision to ``out`` (model, normalizer, evaluation log and a config.json that
    records the selection and every checkpoint's figures); returns the chosen row. Raises
    ValueError where no checkpoint qualifies."""
    rows = evaluate_checkpoints(run, episodes, seed)
    clean = [r for r in rows if r["success_rate"] == 1.0 and r["collision_rate"] == 0.0]
    if not clean:
        raise ValueError(f"no checkpoint of {run} succeeded in every episode without a collision")
    best = min(clean, key=lambda r: r["mean_time"])
    stage(run, best["steps"], out)
    (out / "eval").mkdir(exist_ok=True)
    shutil.copy(run / "eval" / "evaluations.npz", out / "eval" / "evaluations.npz")
    config = json.loads((out / "config.json").read_text())
    config["selected_checkpoint"] = best
    config["selection"] = (f"fastest checkpoint with success in all {episodes} episodes (seeds "
                           f"{seed}..) and no collision, by scara-agents select")
    config["checkpoints"] = rows
    write_json(out / "config.json", config)
    write_digests(out, POLICY_FILES)
    record_trusted(out)
    return best
