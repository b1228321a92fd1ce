"""The comparison's statistics: rliable's interquartile mean with stratified-bootstrap intervals,
the probability of improvement, and the entry every policy gets per condition."""

from __future__ import annotations

import warnings

import numpy as np

from scara_gym.extras import require

TIME_LIMIT = 3.0  # s, the registered episode limit: the time of an episode that never arrives


def time_scores(runs: list[dict]) -> np.ndarray:
    """(runs, episodes) times to target, the time limit where not reached (lower is better)."""
    return np.array([np.where(np.isnan(r["reach_time"]), TIME_LIMIT, r["reach_time"]) for r in runs])


def interval_estimates(scores: dict, function, reps: int, seed: int):
    """rliable's point estimates and 95 % stratified-bootstrap intervals."""
    require("rliable")
    from rliable import library as rly

    with warnings.catch_warnings():  # rliable passes arch a RandomState, which arch deprecates
        warnings.simplefilter("ignore", FutureWarning)
        return rly.get_interval_estimates(scores, function, reps=reps, random_state=np.random.RandomState(seed))


def iqm_with_ci(scores: np.ndarray, reps: int = 2000, seed: int = 0) -> tuple[float, list[float]]:
    """rliable's IQM over runs x tasks and its 95 % stratified-bootstrap interval. One run (a
    classical policy): its episodes are the samples the bootstrap draws (rliable's stratified
    bootstrap resamples runs within each task, which one run cannot show any spread of)."""
    require("rliable")
    from rliable import metrics

    scores = np.asarray(scores)
    if scores.shape[0] == 1:
        scores = scores.T
    point, interval = interval_estimates({"x": scores}, lambda s: np.array([metrics.aggregate_iqm(s)]), reps, seed)
    return float(point["x"][0]), [float(interval["x"][0, 0]), float(interval["x"][1, 0])]


def probability_of_improvement(x: np.ndarray, y: np.ndarray) -> float:
    """rliable.metrics.probability_of_improvement, vectorized over the tasks: per task the
    Mann-Whitney U statistic over all (run of x, run of y) pairs, #(x > y) + #(x = y) / 2,
    divided by the pairs, then averaged over the tasks (rliable's loop calls scipy once per
    task and bootstrap sample: minutes per algorithm with 100 tasks and 2,000 samples)."""
    pairs_x, pairs_y = x[:, None, :], y[None, :, :]
    return float(np.mean((pairs_x > pairs_y).mean(axis=(0, 1)) + 0.5 * (pairs_x == pairs_y).mean(axis=(0, 1))))


def probability_faster(learned: np.ndarray, reference: np.ndarray, reps: int = 2000,
                       seed: int = 0) -> tuple[float, list[float]]:
    """rliable's probability of improvement P(learned faster than reference), with its 95 % CI."""
    point, interval = interval_estimates(
        {"x": [-learned, -reference]}, lambda x, y: np.array([probability_of_improvement(x, y)]), reps, seed)
    return float(point["x"][0]), [float(interval["x"][0, 0]), float(interval["x"][1, 0])]


def training_seconds(config: dict) -> float | None:
    """A run's training time from its config.json; a fine-tuned run's counts the run it started
    from (its registry entry's base)."""
    seconds = config.get("train_seconds")
    return None if seconds is None else seconds + config.get("base_train_seconds", 0.0)


def entry(name: str, kind: str, algorithm: str | None, mode: str, condition: str, runs: list[dict],
          seeds: list[int] | None, note: str = "", train_seconds: list[float] | None = None) -> dict:
    success = np.concatenate([r["success"] for r in runs])
    time_iqm, time_ci = iqm_with_ci(time_scores(runs))
    row = {"name": name, "kind": kind, "algorithm": algorithm, "control_mode": mode, "condition": condition,
           "seeds": seeds, "episodes": int(len(runs[0]["success"])),
           "success_rate": float(success.mean()),
           "collision_rate": float(np.concatenate([r["collisions"] for r in runs]).mean()),
           "time_iqm": time_iqm, "time_ci": time_ci,
           "energy_mean": float(np.mean([r["energy"].mean() for r in runs])),
           "return_mean": float(np.mean([r["return"].mean() for r in runs])), "note": note}
    if seeds is not None:
        row["per_seed"] = [{"seed": s, "success_rate": float(r["success"].mean()),
                            "collision_rate": float(r["collisions"].mean()),
                            "time_mean": float(np.nanmean(r["reach_time"])) if r["success"].any() else None,
                            "energy_mean": float(r["energy"].mean()),
                            "return_mean": float(r["return"].mean())} for s, r in zip(seeds, runs)]
        for item, seconds in zip(row["per_seed"], train_seconds or []):
            item["train_seconds"] = seconds
    return row


def rate_text(rate: float) -> str:
    """A success or collision rate with two decimals, or three where two would round it to
    another value (0.998 is not 1.00: 1 collision in 500 episodes must show)."""
    text = f"{rate:.2f}"
    return text if float(text) == rate else f"{rate:.3f}"
