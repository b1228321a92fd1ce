"""The comparison command: every policy over the same seeds, rliable aggregates, the JSON format."""

import json

import numpy as np
import pytest

pytest.importorskip("rliable")
pytest.importorskip("stable_baselines3")
from agents import compare, training  # noqa: E402

KEYS = {"name", "kind", "algorithm", "seeds", "episodes", "success_rate", "collision_rate", "time_iqm",
        "time_ci", "energy_mean", "condition"}


def test_iqm_and_probability_of_improvement_on_known_scores():
    scores = np.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [100.0, 100.0]])
    iqm, (low, high) = compare.iqm_with_ci(scores, reps=500)
    assert iqm == pytest.approx(2.5)  # the middle half of the 8 scores: 2, 2, 3, 3
    assert low <= iqm <= high
    faster, _ = compare.probability_faster(np.full((3, 2), 1.0), np.full((1, 2), 2.0), reps=200)
    assert faster == 1.0
    tie, _ = compare.probability_faster(np.full((3, 2), 2.0), np.full((1, 2), 2.0), reps=200)
    assert tie == 0.5


def test_comparison_command_writes_every_policy(tmp_path):
    runs = tmp_path / "runs"
    hyper = training.load_hyperparams("td3")
    hyper.update(n_envs=1, learning_starts=50, buffer_size=500, eval_freq=100, eval_episodes=1, snapshot_freq=100)
    for seed in (0, 1):
        training.train("td3", runs / "Scara-C11-v1" / "pd" / "td3" / f"seed{seed}", seed=seed,
                       hyperparams=hyper, total_timesteps=200)
    out = tmp_path / "results"
    entries, traces = compare.compare(runs, ["c11"], episodes=2, verbose=False, bisection_tolerance=0.01)
    names = [e["name"] for e in entries]
    assert names[0] == "pd" and "optimal" in names and names[-1] == "td3"
    assert sum(e["kind"] == "heuristic" for e in entries) == 4  # two variants, smallest safe and +20 %
    for e in entries:
        assert KEYS <= set(e) and e["condition"] == "c11" and e["episodes"] == 2
        assert e["time_ci"][0] <= e["time_iqm"] <= e["time_ci"][1]
    pd, optimal, td3 = entries[0], entries[names.index("optimal")], entries[-1]
    assert pd["collision_rate"] == 1.0 and pd["time_iqm"] == compare.TIME_LIMIT
    assert optimal["success_rate"] == 1.0 and optimal["collision_rate"] == 0.0 and optimal["time_iqm"] < 1.25
    heuristic = [e for e in entries if e["kind"] == "heuristic"]
    assert all(e["success_rate"] == 1.0 and e["collision_rate"] == 0.0 for e in heuristic)
    assert td3["seeds"] == [0, 1] and [s["seed"] for s in td3["per_seed"]] == [0, 1]
    assert 0.0 <= td3["probability_faster_than_heuristic"] <= 1.0
    written = compare.figures(entries, traces, compare.learned_runs(runs), out.mkdir() or out)
    assert {p.name for p in written} == {"comparison_tip_paths.png", "comparison_time_energy.png",
                                        "comparison_learning_curves.png"}
    table = compare.markdown(entries)
    assert "| optimal | optimal | voltage |" in table and "seed 1:" in table
    json.dumps(entries)  # the JSON other tools read
