"""Checkpoint selection (``scara-agents select RUN --out models/NAME``): ship the best checkpoint of a run.

PPO on this task is not monotone: the fastest policies can appear mid-run and the final
one can be slower. ``scara-agents train ppo-residual`` saves a checkpoint about every 100k steps together with
its VecNormalize statistics; this evaluates each one over the same seeds and copies the
fastest checkpoint that succeeds in every episode without a collision (as EvalCallback's
best model, but with the matching normalization statistics) to OUT, with its evaluation
log and a config.json that records the selection.

Only the checkpoints the run's trusted ``checkpoints/SHA256SUMS`` lists are loaded, from the bytes
that were checked against it; a checkpoint file beside them that it does not list is refused unread.
"""

from __future__ import annotations

import math
import re
import shutil
import tempfile
from pathlib import Path

import gymnasium as gym

from agents.algorithms.sb3.policy import PPOPolicy
from agents.files import (
    POLICY_FILES,
    Checked,
    record_trusted,
    require_trusted,
    verify_digests,
    write_atomic,
    write_digests,
    write_json,
)
from agents.policies import run_episode
from scara_gym.model.checks import UserError

CHECKPOINT = re.compile(r"(?:ppo|sac|td3|tqc|crossq)_(?:vecnormalize_)?(\d+)_steps\.(?:zip|pkl)")
"""the names of the checkpoint files SB3's CheckpointCallback writes (prefix: the run's algorithm; model, normalizer)"""


def checked_checkpoints(run: Path) -> tuple[Checked, Checked, list[int]]:
    """(the run's files, its checkpoints' files, the checkpoints' steps in order), read once and
    checked: the run's config.json against its manifest, and every checkpoint against the run's
    trusted checkpoints manifest, which must list every checkpoint file the folder holds."""
    files = verify_digests(run, ("config.json",))
    folder = run / "checkpoints"
    present = [p.name for p in folder.iterdir() if CHECKPOINT.fullmatch(p.name)] if folder.is_dir() else []
    kept = require_trusted(folder, wanted=present)  # pickle: the run's own manifest, trusted, before any loads
    steps = sorted({int(m.group(1)) for m in map(CHECKPOINT.fullmatch, kept.files) if m and m.group(0).endswith("zip")})
    return files, kept, steps


def evaluate_checkpoints(run: Path, episodes: int = 5, seed: int = 5000) -> list[dict]:
    files, kept, all_steps = checked_checkpoints(run)
    config = files.json("config.json")
    kwargs = {k: config["env_kwargs"][k] for k in ("control_mode", "randomize_target")}
    env = gym.make(config.get("env_id", "Scara-C11-v0"), **kwargs)
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for steps in all_steps:
            model_dir = Path(scratch) / str(steps)
            stage(files, kept, steps, model_dir)
            policy = PPOPolicy(env, model_dir, trust=True)  # a private copy of the checked bytes
            results = [run_episode(env, policy, seed=seed + i) for i in range(episodes)]
            times = [r["reach_time"] for r in results if r["success"]]
            rows.append({"steps": steps, "success_rate": len(times) / episodes,
                         "collision_rate": sum(r["collisions"] > 0 for r in results) / episodes,
                         "mean_time": sum(times) / len(times) if times else math.nan})
            print(rows[-1], flush=True)
    return rows


def stage(files: Checked, kept: Checked, steps: int, out: Path) -> None:
    """Checkpoint ``steps`` as a model folder in ``out``, written from the checked bytes."""
    out.mkdir(parents=True, exist_ok=True)
    algo = files.json("config.json").get("algo", "ppo")  # CheckpointCallback's name prefix
    write_atomic(out / "model.zip", kept.bytes(f"{algo}_{steps}_steps.zip"))
    if f"{algo}_vecnormalize_{steps}_steps.pkl" in kept:
        write_atomic(out / "vecnormalize.pkl", kept.bytes(f"{algo}_vecnormalize_{steps}_steps.pkl"))
    write_atomic(out / "config.json", files.bytes("config.json"))


def select_checkpoint(run: Path, out: Path, episodes: int = 5, seed: int = 5000) -> dict:
    """Evaluate every checkpoint of ``run`` and ship the fastest that succeeds in every episode
    without a collision to ``out`` (model, normalizer, evaluation log and a config.json that
    records the selection and every checkpoint's figures); returns the chosen row. Raises
    ValueError where no checkpoint qualifies."""
    rows = evaluate_checkpoints(run, episodes, seed)
    clean = [r for r in rows if r["success_rate"] == 1.0 and r["collision_rate"] == 0.0]
    if not clean:
        raise UserError(f"no checkpoint of {run} succeeded in every episode without a collision")
    best = min(clean, key=lambda r: r["mean_time"])
    files, kept, _ = checked_checkpoints(run)
    stage(files, kept, best["steps"], out)
    (out / "eval").mkdir(exist_ok=True)
    shutil.copy(run / "eval" / "evaluations.npz", out / "eval" / "evaluations.npz")
    config = files.json("config.json")
    config["selected_checkpoint"] = best
    config["selection"] = (f"fastest checkpoint with success in all {episodes} episodes (seeds "
                           f"{seed}..) and no collision, by scara-agents select")
    config["checkpoints"] = rows
    write_json(out / "config.json", config)
    write_digests(out, POLICY_FILES)
    record_trusted(out)
    return best
