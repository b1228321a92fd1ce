"""Robustness curves: success and time to target against a shift's magnitude, per policy.

Each curve scales one parameter (every axis's, for ``axes.*``) by the factors of `CURVES`,
from starts in the protocol's start region (``scara_gym.benchmark.protocol.shift_condition``, on
c11-starts' seeds), or scales the sensor noise of "sensor-noise" (``noise_condition``). Every
point runs the same episodes for every policy; a learned policy runs them with each of its seeds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from agents.experiments.comparison import CLASSICAL_SOURCES, ROBUST_LABEL, robust_shield_pd, shield_pd
from agents.experiments.evaluation import cached_evaluation, condition_description, learned_episodes, learned_runs
from agents.experiments.report import curve_figure
from agents.experiments.statistics import iqm_with_ci, time_scores
from agents.experiments.tuning import tune_heuristic
from agents.files import write_json
from agents.policies import DecHeuristic
from scara_gym.benchmark.protocol import ENV_ID, evaluate, noise_condition, shift_condition
from scara_gym.model.checks import UserError

CURVES = {
    "load mass": ("arm.load_mass", (1.0, 1.5, 2.0, 2.5, 3.0)),
    "current limits": ("axes.*.current_limit", (1.0, 0.9, 0.85, 0.8, 0.7)),
    "motor resistances": ("axes.*.resistance", (1.0, 1.1, 1.2, 1.3, 1.5)),
    "sensor noise": (None, (0.0, 1.0, 2.0, 5.0, 10.0)),
}
"""curve -> (dotted parameter path, or None for the sensor noise; the factors of its points)"""
LEARNED = ("torch-ppo-residual-fast", "torch-ppo-residual-dr", "torch-ppo-residual-random-replay", "ppo-residual")
"""the learned baselines drawn on the curves (every seed)"""


def point_condition(curve: str, factor: float):
    path, _ = CURVES[curve]
    return noise_condition(factor) if path is None else shift_condition(path, factor)


def robustness_curves(runs_root: Path | None, episodes: int = 20, learned: tuple[str, ...] = LEARNED,
                      cache: Path | None = None, robust_shield: bool = False, verbose: bool = True) -> dict:
    """{"curves": {curve: {"factors", "policies": {label: {"success", "collisions", "time_iqm"}}}}}:
    every point of every curve for PD behind the shield (and the robust shield), the heuristic at
    its tuned distance and with the margin, and the ``learned`` runs found under ``runs_root``."""
    tuned = tune_heuristic("continue")
    classical = {
        "pd + shield": shield_pd,
        f"dec-continue, tuned (d={tuned['distance']:.4f} m)":
            lambda env: DecHeuristic(env, "continue", critical_distance=tuned["distance"]),
        f"dec-continue, margin (d={tuned['margin_distance']:.4f} m)":
            lambda env: DecHeuristic(env, "continue", critical_distance=tuned["margin_distance"]),
    }
    if robust_shield:
        classical[ROBUST_LABEL] = robust_shield_pd
    groups = {k: v for k, v in (learned_runs(runs_root) if runs_root else {}).items() if k[0] in learned}
    return {"env_id": ENV_ID, "episodes": episodes, "curves": curve_points(classical, groups, episodes, cache, verbose),
            "heuristic": tuned}


ONLY_CURVES = {"robust-shield": (ROBUST_LABEL, robust_shield_pd)}
"""the policies ``curves --only`` evaluates alone: kind -> (label, factory of the env)"""


def merge_curves(published: dict, kinds, verbose: bool = True, cache: Path | None = None) -> dict:
    """``published`` curves (curves.json's record) with the points of ``kinds`` (ONLY_CURVES)
    evaluated by the curves' own loop (curve_points: the same conditions, and the published
    episode count) and put in, replacing theirs; every other policy's points are kept as
    published. UserError where the published factors are not today's."""
    classical = {ONLY_CURVES[k][0]: ONLY_CURVES[k][1] for k in kinds}
    fresh = curve_points(classical, {}, published["episodes"], verbose=verbose, cache=cache)
    data = {**published, "curves": {k: {**v, "policies": dict(v["policies"])} for k, v in published["curves"].items()}}
    for curve, points in fresh.items():
        if curve not in data["curves"] or points["factors"] != data["curves"][curve]["factors"]:
            had = data["curves"].get(curve, {}).get("factors")
            raise UserError(f"--merge: curve {curve!r} has the factors {had} there, not today's {points['factors']}; "
                            "run the curves again in full")
        for label in classical:
            data["curves"][curve]["policies"][label] = points["policies"][label]
    return data


def curve_points(classical: dict, groups: dict, episodes: int, cache: Path | None = None,
                 verbose: bool = True) -> dict:
    """{curve: {"factors", "policies": {label: row}}} for the ``classical`` policies (label -> a
    factory of the env) and the learned run ``groups`` ((algorithm, mode) -> run folders): the same
    episodes at every point for every policy, every seed of a learned run."""
    out = {}
    for curve, (_, factors) in CURVES.items():
        policies: dict[str, dict] = {}
        for factor in factors:
            condition = point_condition(curve, factor)
            results = {label: [_classical(label, factory, condition, episodes, cache)] for label, factory in classical.items()}
            for (algorithm, mode), run_dirs in sorted(groups.items()):
                results[algorithm] = [learned_episodes(d, condition, mode, episodes, cache) for d in run_dirs]
            for label, runs in results.items():
                row = policies.setdefault(label, {"success": [], "collisions": [], "time_iqm": [], "seeds": len(runs)})
                row["success"].append(float(np.mean([r["success"].mean() for r in runs])))
                row["collisions"].append(float(np.mean([r["collisions"].mean() for r in runs])))
                row["time_iqm"].append(iqm_with_ci(time_scores(runs), reps=200)[0])
                if verbose:
                    print(f"[{curve} x{factor:g}] {label}: success {row['success'][-1]:.2f}, collisions "
                          f"{row['collisions'][-1]:.2f}, time IQM {row['time_iqm'][-1]:.3f} s", flush=True)
        out[curve] = {"factors": list(factors), "policies": policies}
    return out


def _classical(label: str, factory, condition, episodes: int, cache: Path | None) -> dict:
    """A classical policy's episodes at a curve's point, from ``cache`` where it keeps them (the
    comparison's cached_evaluation: the policies' and the shield's source, the label, which names
    the heuristic's distance, and the point's condition and seeds), so that a stopped run of the
    curves goes on where it stopped."""
    def run() -> dict:
        result = evaluate(condition, factory, "pd", episodes)
        result.pop("condition")
        return result

    return cached_evaluation(cache, "curve", CLASSICAL_SOURCES, [label, "pd", *condition_description(condition, episodes)],
                             run)


def write_curves(data: dict, out: Path) -> list[Path]:
    """curves.json and the figure (agents.experiments.report.curve_figure) under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "curves.json", data, indent=1)
    return [out / "curves.json", curve_figure(data, out / "comparison_robustness.png")]
