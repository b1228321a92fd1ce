"""``python -m agents.evaluate``: run policies over the same fixed seeds, write tables and plots.

    python -m agents.evaluate --policies pd dec-continue:0.06 dec-restart:0.06 ppo:ppo_pd \\
        --control-mode pd --episodes 100 --out results/pd

Policy specs: ``pd``; ``dec-continue[:d]`` and ``dec-restart[:d]`` (the seed's heuristic
with trigger distance d [m]); ``ppo:NAME`` (a shipped model, e.g. ``ppo_pd``) or
``ppo:DIR`` (a model saved by agents.train); ``sb3:DIR`` (any run of agents.training:
PPO, SAC, TD3); ``torchppo:DIR`` (a run of agents.torch_ppo); ``optimal`` (the minimum-time reference of agents.optimal, "voltage" mode,
best on ``--env-id Scara-C11-v1``, the physics it was verified on); ``shield:SPEC`` (the policy of SPEC behind
agents.shield's model-predictive shield, e.g. ``shield:pd``). Writes, under ``--out`` only: ``table.md``,
``table.csv``, ``tip_paths.png``, ``wall_and_height.png``, ``NAME_results.json`` for each
PPO model (the format of a shipped model's ``results.json``) and, for PPO models with
evaluation logs, ``learning_curves.png``.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

from agents.policies import DecHeuristic, PDPolicy, run_episode
from scara_gym import ENV_ID, ENV_IDS

COLUMNS = ("policy", "episodes", "success rate", "collision rate", "mean time to target [s]",
           "worst time to target [s]", "energy [J]", "peak current [Imax]", "return")


def make_policy(spec: str, env):
    kind, _, arg = spec.partition(":")
    if kind == "shield":
        from agents.shield import Shield
        if not arg:
            raise ValueError("shielded policies are given as shield:SPEC, e.g. shield:pd or shield:torchppo:RUN_DIR")
        return Shield(env, make_policy(arg, env))
    if kind == "pd":
        return PDPolicy(env)
    if kind in ("dec-continue", "dec-restart"):
        distance = float(arg) if arg else 0.06
        return DecHeuristic(env, variant=kind.split("-")[1], critical_distance=distance)
    if kind == "ppo":
        from agents.ppo import PPOPolicy
        if not arg:
            raise ValueError("ppo policies are given as ppo:NAME (shipped) or ppo:MODEL_DIR")
        return PPOPolicy(env, arg)
    if kind == "sb3":
        from agents.training import SB3Policy
        if not arg:
            raise ValueError("sb3 policies are given as sb3:RUN_DIR (a folder written by agents.training)")
        return SB3Policy(env, arg)
    if kind == "torchppo":
        from agents.torch_ppo import TorchPPOPolicy
        if not arg:
            raise ValueError("torch PPO policies are given as torchppo:RUN_DIR (a folder written by agents.torch_ppo)")
        return TorchPPOPolicy(env, arg)
    if kind == "optimal":
        from agents.optimal import OptimalPolicy
        return OptimalPolicy(env)
    raise ValueError(f"unknown policy {spec!r}; use pd, dec-continue[:d], dec-restart[:d], optimal, "
                     "ppo:NAME_OR_DIR, sb3:RUN_DIR, torchppo:RUN_DIR or shield:SPEC")


def evaluate(policies: list[str], control_mode: str = "pd", randomize_target: bool = False,
             episodes: int = 100, seed: int = 1000, record: int = 3,
             env_id: str = ENV_ID) -> tuple[list[dict], dict]:
    """Summary rows and recorded traces (first `record` episodes) per policy."""
    import gymnasium as gym

    import scara_gym  # noqa: F401

    rows, traces = [], {}
    for spec in policies:
        env = gym.make(env_id, control_mode=control_mode, randomize_target=randomize_target)
        policy = make_policy(spec, env)
        results = [run_episode(env, policy, seed=seed + i, record=i < record) for i in range(episodes)]
        traces[policy.name] = [r["trace"] for r in results[:record]]
        reach = np.array([r["reach_time"] for r in results if r["success"]])
        rows.append({
            "policy": policy.name,
            "episodes": episodes,
            "success rate": np.mean([r["success"] for r in results]),
            "collision rate": np.mean([r["collisions"] > 0 for r in results]),
            "mean time to target [s]": reach.mean() if reach.size else np.nan,
            "worst time to target [s]": reach.max() if reach.size else np.nan,
            "energy [J]": np.mean([r["energy"] for r in results]),
            "peak current [Imax]": np.max([r["peak_current_fraction"] for r in results]),
            "return": np.mean([r["return"] for r in results]),
            "outcomes": [{"success": r["success"], "collisions": r["collisions"],
                          "reach_time": None if np.isnan(r["reach_time"]) else r["reach_time"]} for r in results],
        })
    return rows, traces


def _cell(value) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, (int, np.integer)):
        return str(value)
    return "-" if np.isnan(value) else f"{value:.4f}"


def markdown(rows: list[dict]) -> str:
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(_cell(row[c]) for c in COLUMNS) + " |" for row in rows]
    return "\n".join(lines)


def write_outputs(rows, traces, out: Path, model_dirs: list[Path], params) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    (out / "table.md").write_text(markdown(rows) + "\n")
    with open(out / "table.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    written = [out / "table.md", out / "table.csv"]
    obs = params.obstacle

    fig, ax = plt.subplots(figsize=(6.5, 6))
    ax.axvspan(obs.x_position - obs.critical_distance, obs.x_position + obs.critical_distance, color="0.88")
    ax.axvline(obs.x_position, color="k", lw=2, label="wall (x_obs)")
    for (name, runs), color in zip(traces.items(), plt.cm.tab10.colors):
        for k, trace in enumerate(runs):
            ax.plot(trace[:, 1], trace[:, 2], color=color, lw=1.2, label=name if k == 0 else None)
    ax.set(xlabel="x [m]", ylabel="y [m]", title="Tool-tip paths (first episodes)", aspect="equal")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "tip_paths.png", dpi=110)
    plt.close(fig)
    written.append(out / "tip_paths.png")

    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for (name, runs), color in zip(traces.items(), plt.cm.tab10.colors):
        trace = runs[0]
        top.plot(trace[:, 0], trace[:, 3], color=color, label=name)
        bottom.plot(trace[:, 0], trace[:, 5], color=color, label=name)
    top.axhspan(-obs.critical_distance, obs.critical_distance, color="0.88")
    top.axhline(0, color="k", lw=1)
    top.set(ylabel="x_tip - x_obs [m]", title="Distance to the wall and height (first episode; seed Fig. 4, 6, 7)")
    bottom.axhline(obs.height, color="k", lw=1, label="h_obs")
    bottom.set(xlabel="t [s]", ylabel="q3 [m]")
    top.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "wall_and_height.png", dpi=110)
    plt.close(fig)
    written.append(out / "wall_and_height.png")

    curves = [(d, np.load(d / "eval" / "evaluations.npz")) for d in model_dirs
              if (d / "eval" / "evaluations.npz").exists()]
    if curves:
        fig, ax = plt.subplots(figsize=(7, 4))
        for model_dir, data in curves:
            mean = data["results"].mean(axis=1)
            ax.plot(data["timesteps"], mean, label=model_dir.name)
        ax.set(xlabel="environment steps", ylabel="mean evaluation return", title="PPO learning curves")
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / "learning_curves.png", dpi=110)
        plt.close(fig)
        written.append(out / "learning_curves.png")
    return written


def main(argv: list[str] | None = None) -> list[dict]:
    from scara_gym import DEFAULT_PARAMS

    parser = argparse.ArgumentParser(prog="python -m agents.evaluate", description=__doc__.split("\n\n")[0])
    parser.add_argument("--policies", nargs="+", default=["pd", "dec-continue", "dec-restart"])
    parser.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID,
                        help="the shipped PPO agents and tables use Scara-C11-v0; the optimal reference Scara-C11-v1")
    parser.add_argument("--control-mode", choices=("pd", "voltage"), default="pd")
    parser.add_argument("--randomize-target", action="store_true")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1000, help="episode i uses seed + i")
    parser.add_argument("--out", type=Path, default=Path("results"))
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    rows, traces = evaluate(args.policies, args.control_mode, args.randomize_target, args.episodes, args.seed,
                            env_id=args.env_id)
    ppo_specs = [spec for spec in args.policies if spec.startswith("ppo:")]
    if ppo_specs:  # stable-baselines3 (the train extra) only where a PPO agent is evaluated
        from agents.ppo import resolve_model
    model_dirs = [resolve_model(spec.split(":", 1)[1]) for spec in ppo_specs]
    write_outputs(rows, traces, args.out, model_dirs, DEFAULT_PARAMS)
    for spec, row in zip(args.policies, rows):
        if spec.startswith("ppo:"):  # the figures a model is tested against once shipped (its results.json)
            name = resolve_model(spec.split(":", 1)[1]).name
            (args.out / f"{name}_results.json").write_text(json.dumps({
                "seed": args.seed, "episodes": args.episodes, "randomize_target": args.randomize_target,
                "success_rate": row["success rate"], "collision_rate": row["collision rate"],
                "mean_time_to_target": row["mean time to target [s]"],
                "worst_time_to_target": row["worst time to target [s]"],
                "episodes_outcomes": row["outcomes"],
                "command": "python -m agents.evaluate " + " ".join(sys.argv[1:] if argv is None else argv)},
                indent=2))
    print(markdown(rows))
    return rows


if __name__ == "__main__":
    main()
