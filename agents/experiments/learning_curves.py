"""Learning curves: a run's checkpoints scored against the environment steps they were trained for.

A run tagged "learning-curve" (agents.experiments.registry) trains on the draws of one protocol
condition (its ``trained_on``) to a large budget and keeps a checkpoint every 250k steps
(ppo.yml's curve blocks). `learning_curve` scores the checkpoints at doubling budgets
(250k, 500k, 1M, ... and the last one) on that condition's *tuning* episodes
(scara_gym.benchmark.protocol.tuning): the budget a published row is trained for is read off
this curve, so it is chosen on tuning episodes and never on the evaluation it is scored on.

Each point: success at every band (1e-3, 1e-2, 5e-2), collisions, and the IQM time to target,
per seed; the raw per-episode arrays are written beside the summary. The plateau is stated with
the issue's rule: less than 1 % change per doubling of the budget over the last doubling (success
in percentage points at each band, the time IQM relative), else "still changing".
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from agents.algorithms.sb3.policy import SB3Policy
from agents.experiments.checkpoints import checked_checkpoints, stage
from agents.experiments.evaluation import OneTorchThread
from agents.experiments.registry import RUNS, spec
from agents.experiments.report import learning_curve_figure
from agents.experiments.statistics import time_scores
from agents.files import json_record, write_json
from scara_gym.benchmark.episodes import BAND_NAMES, band_keys
from scara_gym.benchmark.protocol import ENV_ID, evaluate, tuning
from scara_gym.model.checks import UserError

PLATEAU = 0.01
"""less than this change per doubling of the budget (issue 58): success in rate, time relative"""


def budgets(steps: list[int], first: int | None = None) -> list[int]:
    """The checkpoints' steps a curve scores: first (default: the first checkpoint), 2 first,
    4 first, ... where a checkpoint is there, and the last checkpoint."""
    if not steps:
        return []
    kept, budget = [], steps[0] if first is None else first
    while budget <= steps[-1]:
        if budget in steps:
            kept.append(budget)
        budget *= 2
    return kept if kept and kept[-1] == steps[-1] else [*kept, steps[-1]]


def point(result: dict) -> dict:
    """A checkpoint's figures over one seed's episodes: success and IQM time at every band, collisions."""
    row = {"collision_rate": float(np.mean(np.asarray(result["collisions"]) > 0))}
    for band in BAND_NAMES:
        reached, times = band_keys(band)
        row[f"success_{band}"] = float(np.mean(result[reached]))
        scores = np.sort(time_scores([result], times)[0])
        quarter = len(scores) // 4
        row[f"time_iqm_{band}"] = float(np.mean(scores[quarter:len(scores) - quarter]))  # 3 s where not reached
    return row


def plateau(points: list[dict], budgets_: list[int]) -> dict:
    """The rule over the last doubling of the budget (the last budget against the largest that is
    at most half of it), on the seeds' mean figures: {"from", "to", "changes", "plateau"}."""
    last = budgets_[-1]
    earlier = [i for i, b in enumerate(budgets_) if 2 * b <= last]
    if not earlier:
        return {"plateau": None, "why": "fewer than one doubling of the budget scored"}
    a, b = points[earlier[-1]], points[-1]
    changes = {f"success_{band}": b[f"success_{band}"] - a[f"success_{band}"] for band in BAND_NAMES}
    changes.update({f"time_iqm_{band}": (b[f"time_iqm_{band}"] - a[f"time_iqm_{band}"]) / a[f"time_iqm_{band}"]
                    for band in BAND_NAMES})
    doublings = float(np.log2(last / budgets_[earlier[-1]]))
    per_doubling = {key: value / doublings for key, value in changes.items()}
    return {"from": budgets_[earlier[-1]], "to": last, "change_per_doubling": per_doubling,
            "plateau": bool(all(abs(v) < PLATEAU for v in per_doubling.values()))}


def learning_curve(name: str, run_dirs: list[Path], episodes: int = 50, out: Path | None = None,
                   verbose: bool = True, first_budget: int | None = None, merge: Path | None = None) -> dict:
    """Score every seed's checkpoints of the registered run ``name`` (folders ``run_dirs``, one per
    seed) at `budgets` (from ``first_budget``) on ``episodes`` tuning episodes of its ``trained_on`` condition; with
    ``out``, write ``NAME.json`` (summary, plateau, raw arrays) and ``NAME.png`` there. With ``merge``
    (a NAME.json written before, on the same episodes), its seeds that ``run_dirs`` do not score
    again are kept: seeds trained in different sittings make one curve without their checkpoints
    being kept for ever."""
    run = spec(name)
    if "learning-curve" not in run.tags or run.trained_on is None:
        raise UserError(f"{name} is not a learning-curve run (tag 'learning-curve' and a trained_on condition); "
                         "those are: " + ", ".join(sorted(n for n, r in _curve_runs().items())))
    if not run_dirs:
        raise UserError(f"no run folders of {name} given")
    condition = tuning(run.trained_on, episodes)
    scored_on = f"{condition.name}: {episodes} episodes from seed {condition.seed}"
    seeds, raw, env_ids = {}, {}, set()
    for run_dir in map(Path, run_dirs):
        config = json_record(run_dir / "config.json")
        env_ids.add(config["env_id"])
        files, kept, steps = checked_checkpoints(run_dir)
        chosen = budgets(steps, first_budget)
        rows, arrays = [], {}
        with tempfile.TemporaryDirectory() as scratch:
            for budget in chosen:
                model_dir = Path(scratch) / str(budget)
                stage(files, kept, budget, model_dir)
                with OneTorchThread(lambda env, d=model_dir: SB3Policy(env, d, trust=True)) as factory:  # checked bytes
                    result = evaluate(condition, factory, config["env_kwargs"]["control_mode"], env_id=config["env_id"],
                                      record=0)
                rows.append({"steps": budget, **point(result)})
                arrays[str(budget)] = {k: _raw(v) for k, v in result.items()
                                       if k.startswith(("success", "reach_time", "collisions"))}
                if verbose:
                    print(f"{run_dir}: {budget:,} steps {rows[-1]}", flush=True)
        seeds[str(config["seed"])] = rows
        raw[str(config["seed"])] = arrays
    if merge is not None:
        env_ids.add(_merge_seeds(json_record(merge), name, scored_on, episodes, seeds, raw, merge))
    if len(env_ids) != 1:
        raise UserError(f"the run folders of {name} were trained on different ids {sorted(env_ids)}")
    common = sorted(set.intersection(*({r["steps"] for r in rows} for rows in seeds.values())))
    mean = [{key: float(np.mean([next(r for r in rows if r["steps"] == b)[key] for rows in seeds.values()]))
             for key in seeds[next(iter(seeds))][0]} for b in common]
    data = {"run": name, "description": run.description, "env_id": env_ids.pop(), "trained_on": run.trained_on,
            "scored_on": scored_on,
            "episodes": episodes, "budgets": common, "seeds": seeds, "mean": mean,
            "plateau": plateau(mean, common) if common else {"plateau": None, "why": "no budget common to the seeds"},
            "rule": f"plateau: under {PLATEAU:.0%} change per doubling of the budget over the last doubling "
                    "(success rates in absolute terms at each band, IQM times relative), on the seeds' means",
            "raw": raw}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / f"{name}.json", data, indent=None)  # compact: the raw episodes are most of it
        learning_curve_figure(data, out / f"{name}.png")
    return data


def _merge_seeds(published: dict, name: str, scored_on: str, episodes: int, seeds: dict, raw: dict,
                 path: Path) -> str:
    """Add to ``seeds`` and ``raw`` the seeds of the ``published`` curve they lack, once it is the
    same run scored on the same episodes; returns its env id."""
    for key, wanted in (("run", name), ("scored_on", scored_on), ("episodes", episodes)):
        if published.get(key) != wanted:
            raise UserError(f"--merge {path}: its {key} is {published.get(key)!r}, not {wanted!r}; a curve merges "
                            "only with one of the same run scored on the same tuning episodes")
    for seed, rows in published["seeds"].items():
        if seed not in seeds:
            seeds[seed], raw[seed] = rows, published["raw"][seed]
    return published["env_id"]


def _raw(values) -> list:
    """One episode array as strict JSON: flags and counts as integers, times in s to the microsecond,
    null where an episode did not reach its band (NaN is not JSON)."""
    array = np.asarray(values)
    if array.dtype.kind in "biu":
        return array.astype(int).tolist()
    return [None if not np.isfinite(x) else round(float(x), 6) for x in array]


def _curve_runs() -> dict:
    return {n: r for n, r in RUNS.items() if "learning-curve" in r.tags}


def run_folders(name: str, runs_root: Path, env_id: str = ENV_ID, control_mode: str = "pd") -> list[Path]:
    """The finished seed folders of ``name`` under ``runs_root`` (laid out ENV_ID/MODE/NAME/seedN)."""
    folder = Path(runs_root) / env_id / control_mode / name
    return sorted(p for p in folder.glob("seed*") if (p / "config.json").is_file()) if folder.is_dir() else []
