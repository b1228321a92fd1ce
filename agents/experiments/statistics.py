"""The comparison's statistics: rliable's interquartile mean with stratified-bootstrap intervals,
the probability of improvement, and the entry every policy gets per condition.

An entry scores every band of scara_gym.benchmark.episodes (``BAND_NAMES``): the C11 band 1e-3 as
``success_rate`` and ``time_iqm`` / ``time_ci``; each looser band NAME (1e-2, 5e-2) as
``success_rate_NAME`` and ``time_iqm_NAME`` / ``time_ci_NAME`` (the time to the band, the time
limit where not reached, as for the C11 band); per seed ``success_rate_NAME`` and ``time_mean_NAME``.
The normalized time score (`time_score_fields`) is added by the comparison, which has the
references' episodes.
"""

from __future__ import annotations

import warnings

import numpy as np

from agents.experiments.entries import Entry
from scara_gym.benchmark.episodes import BANDS, band_keys
from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.extras import require

TIME_LIMIT = 3.0  # s, the registered episode limit: the time of an episode that never arrives


def time_scores(runs: list[dict], key: str = "reach_time") -> np.ndarray:
    """(runs, episodes) times to target (``key``: the per-episode times, e.g. a looser band's
    ``reach_time_1e-2``), the time limit where not reached (lower is better)."""
    return np.array([np.where(np.isnan(r[key]), TIME_LIMIT, r[key]) for r in runs])


def normalized_time_scores(times: np.ndarray, zero: np.ndarray, one: np.ndarray) -> np.ndarray:
    """(runs, episodes) normalized time scores (zero_j - t_j) / (zero_j - one_j) of the times
    ``times`` (time_scores: the time limit where not reached) against two references' times per
    episode j: ``zero`` scores 0 (the time limit where it did not reach the target), ``one`` scores 1
    (NaN where it did not). An episode whose ``one`` did not reach the target, or was not sooner
    than ``zero``, has no score (NaN): no scale to measure on. Not clipped: above 1 is faster
    than the reference, below 0 slower than the zero policy (a miss is scored at the time limit)."""
    times, zero, one = np.atleast_2d(times), np.asarray(zero, dtype=float), np.asarray(one, dtype=float)
    scored = np.isfinite(one) & (one < zero)
    span = np.where(scored, zero - np.where(scored, one, 0.0), 1.0)
    return np.where(scored, (zero - times) / span, np.nan)


def time_score_fields(runs: list[dict], zero_runs: list[dict], one_runs: list[dict], reference: str,
                      seeds: list[int] | None = None) -> dict:
    """An entry's normalized time score (normalized_time_scores: 0 = the first run of ``zero_runs``,
    1 = the first of ``one_runs``, per episode at the C11 band) over ``runs``: "time_score_iqm" and
    its 95 % interval "time_score_ci" (rliable, as time_iqm) over the episodes that have a score
    ("time_score_episodes" of them), "time_score_reference" (what scores 1) and, with ``seeds``,
    each seed's mean as ``time_score_mean`` of its per_seed item (returned as "per_seed_scores").
    No episode scored: {"time_score_reference": reference, "time_score_episodes": 0}."""
    zero, one = time_scores(zero_runs[:1])[0], one_runs[0]["reach_time"]
    scores = normalized_time_scores(time_scores(runs), zero, one)
    kept = np.isfinite(scores[0])
    out = {"time_score_reference": reference, "time_score_episodes": int(kept.sum())}
    if not kept.any():
        return out
    scores = scores[:, kept]
    out["time_score_iqm"], out["time_score_ci"] = iqm_with_ci(scores)
    if seeds is not None:
        out["per_seed_scores"] = [float(s.mean()) for s in scores]
    return out


def interval_estimates(scores: dict, function, reps: int, seed: int):
    """rliable's point estimates and 95 % stratified-bootstrap intervals, the same for the same
    scores and seed. rliable's stratified bootstrap draws its resamples from numpy's global
    generator, whatever random_state it is given (rliable 1.2's update_indices): that generator
    is seeded here for the call and given back its state after it."""
    require("rliable")
    from rliable import library as rly

    state = np.random.get_state()
    np.random.seed(seed)
    try:
        with warnings.catch_warnings():  # rliable passes arch a RandomState, which arch deprecates
            warnings.simplefilter("ignore", FutureWarning)
            return rly.get_interval_estimates(scores, function, reps=reps, random_state=np.random.RandomState(seed))
    finally:
        np.random.set_state(state)


def iqm(scores: np.ndarray) -> float:
    """rliable's aggregate_iqm (scipy.stats.trim_mean(scores, 0.25, axis=None)), the same number to
    the last bit: the same partition of the flattened scores and the mean of the same slice, without
    scipy's per-call argument handling, which took 95 % of a bootstrap's time (2,000 calls per
    interval). Scores that are not all finite go to rliable's own function (scipy's NaN rules)."""
    flat = np.ravel(scores)
    if flat.size == 0 or not np.isfinite(flat).all():
        from rliable import metrics

        return metrics.aggregate_iqm(scores)
    low = int(0.25 * flat.size)
    high = flat.size - low
    trimmed = np.partition(flat, (low, high - 1))[low:high]
    return np.mean(trimmed if np.issubdtype(trimmed.dtype, np.floating) else trimmed.astype(np.float64))


def iqm_with_ci(scores: np.ndarray, reps: int = 2000, seed: int = 0) -> tuple[float, list[float]]:
    """rliable's IQM over runs x tasks and its 95 % stratified-bootstrap interval. One run (a
    classical policy): its episodes are the samples the bootstrap draws (rliable's stratified
    bootstrap resamples runs within each task, which one run cannot show any spread of)."""
    scores = np.asarray(scores)
    if scores.shape[0] == 1:
        scores = scores.T
    point, interval = interval_estimates({"x": scores}, lambda s: np.array([iqm(s)]), reps, seed)
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
          seeds: list[int] | None, note: str = "", train_seconds: list[float] | None = None,
          env_id: str = ENV_ID) -> dict:
    """The record of a row without a heuristic's or a shield's fields (Entry.record), from its runs' episodes."""
    return Entry(name, kind, algorithm, mode, condition, env_id, None if seeds is None else tuple(seeds), note=note,
                 figures=figures(runs, seeds, train_seconds)).record()


def figures(runs: list[dict], seeds: list[int] | None, train_seconds: list[float] | None = None) -> dict:
    """An entry's numbers from its runs' per-episode arrays (one run per seed, or one): success,
    collisions, time (IQM with its 95 % CI, rliable), energy and return, at each band, and with
    ``seeds`` every seed's own ("per_seed", with its training time where given)."""
    success = np.concatenate([r["success"] for r in runs])
    time_iqm, time_ci = iqm_with_ci(time_scores(runs))
    row = {"episodes": int(len(runs[0]["success"])),
           "success_rate": float(success.mean()),
           "collision_rate": float(np.concatenate([r["collisions"] for r in runs]).mean()),
           "time_iqm": time_iqm, "time_ci": time_ci,
           "energy_mean": float(np.mean([r["energy"].mean() for r in runs])),
           "return_mean": float(np.mean([r["return"].mean() for r in runs]))}
    for band in BANDS:  # the looser bands (module docstring)
        reached, times = band_keys(band)
        row[f"success_rate_{band}"] = float(np.concatenate([r[reached] for r in runs]).mean())
        row[f"time_iqm_{band}"], row[f"time_ci_{band}"] = iqm_with_ci(time_scores(runs, times))
    if seeds is not None:
        row["per_seed"] = [{"seed": s, "success_rate": float(r["success"].mean()),
                            "collision_rate": float(r["collisions"].mean()),
                            "time_mean": float(np.nanmean(r["reach_time"])) if r["success"].any() else None,
                            "energy_mean": float(r["energy"].mean()),
                            "return_mean": float(r["return"].mean()),
                            **_band_figures(r)} for s, r in zip(seeds, runs)]
        for item, seconds in zip(row["per_seed"], train_seconds or []):
            item["train_seconds"] = seconds
    return row


def _band_figures(run: dict) -> dict:
    """One seed's success rate and mean time (over the episodes that reach it) at each looser band."""
    out = {}
    for band in BANDS:
        reached, times = band_keys(band)
        out[f"success_rate_{band}"] = float(run[reached].mean())
        out[f"time_mean_{band}"] = float(np.nanmean(run[times])) if run[reached].any() else None
    return out


def rate_interval(rate: float, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The Clopper-Pearson interval of a rate observed as ``rate`` over ``n`` episodes (exact for
    a binomial count: 0 in 150 gives [0, 0.0243], "at most 2.4 %")."""
    from scipy.stats import beta

    k = int(round(rate * n))
    tail = (1.0 - confidence) / 2.0
    low = 0.0 if k == 0 else float(beta.ppf(tail, k, n - k + 1))
    high = 1.0 if k == n else float(beta.ppf(1.0 - tail, k + 1, n - k))
    return low, high


def episodes_of(e: dict) -> int:
    """The episodes an entry's rates count: its episodes per seed times its seeds (one for a classical policy)."""
    return int(e["episodes"]) * max(1, len(e.get("seeds") or ()))


def rate_claim(rate: float, n: int) -> str:
    """A rate published from n episodes with its 95 % interval: "0 of 150 (at most 2.4 %)" or
    "3 of 150 (2.0 %, 95 % CI 0.4-5.7 %)"."""
    k = int(round(rate * n))
    low, high = rate_interval(rate, n)
    if k == 0:
        return f"0 of {n} (at most {100 * high:.1f} %)"
    return f"{k} of {n} ({100 * rate:.1f} %, 95 % CI {100 * low:.1f}-{100 * high:.1f} %)"


def rate_text(rate: float) -> str:
    """A success or collision rate with two decimals, or three where two would round it to
    another value (0.998 is not 1.00: 1 collision in 500 episodes must show)."""
    text = f"{rate:.2f}"
    return text if float(text) == rate else f"{rate:.3f}"
