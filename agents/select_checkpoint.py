"""``python -m agents.select_checkpoint RUN --out models/NAME``: ship the best checkpoint of a run.

PPO on this task is not monotone: the fastest policies can appear mid-run and the final
one can be slower. agents.train saves a checkpoint about every 100k steps together with
its VecNormalize statistics; this evaluates each one over the same seeds and copies the
fastest checkpoint that succeeds in every episode without a collision (as EvalCallback's
best model, but with the matching normalization statistics) to OUT, with its evaluation
log and a config.json that records the selection.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import tempfile
from pathlib import Path


def evaluate_checkpoints(run: Path, episodes: int = 5, seed: int = 5000) -> list[dict]:
    import gymnasium as gym

    import scara_gym  # noqa: F401
    from agents.policies import run_episode
    from agents.ppo import PPOPolicy
    from scara_gym import ENV_ID

    config = json.loads((run / "config.json").read_text())
    kwargs = {k: config["env_kwargs"][k] for k in ("control_mode", "randomize_target")}
    env = gym.make(config.get("env_id", ENV_ID), **kwargs)
    rows = []
    checkpoints = sorted(run.glob("checkpoints/ppo_[0-9]*_steps.zip"), key=lambda p: int(p.stem.split("_")[1]))
    with tempfile.TemporaryDirectory() as scratch:
        for checkpoint in checkpoints:
            steps = int(checkpoint.stem.split("_")[1])
            model_dir = Path(scratch) / str(steps)
            stage(run, steps, model_dir)
            policy = PPOPolicy(env, model_dir)
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


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m agents.select_checkpoint", description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="the --out folder of agents.train")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--seed", type=int, default=5000)
    args = parser.parse_args(argv)
    rows = evaluate_checkpoints(args.run, args.episodes, args.seed)
    clean = [r for r in rows if r["success_rate"] == 1.0 and r["collision_rate"] == 0.0]
    if not clean:
        raise SystemExit("no checkpoint succeeded in every episode without a collision")
    best = min(clean, key=lambda r: r["mean_time"])
    stage(args.run, best["steps"], args.out)
    (args.out / "eval").mkdir(exist_ok=True)
    shutil.copy(args.run / "eval" / "evaluations.npz", args.out / "eval" / "evaluations.npz")
    config = json.loads((args.out / "config.json").read_text())
    config["selected_checkpoint"] = best
    config["selection"] = (f"fastest checkpoint with success in all {args.episodes} episodes (seeds "
                           f"{args.seed}..) and no collision, by python -m agents.select_checkpoint")
    config["checkpoints"] = rows
    (args.out / "config.json").write_text(json.dumps(config, indent=2))
    return best


if __name__ == "__main__":
    main()
