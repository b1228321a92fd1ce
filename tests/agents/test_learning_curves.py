"""Learning curves: a learning-curve run's checkpoints scored at doubling budgets on its condition's tuning episodes."""

import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
from agents.experiments import learning_curves  # noqa: E402
from agents.experiments.registry import RUNS, RunSpec  # noqa: E402
from agents.experiments.runs import hyperparams_of, train_run  # noqa: E402
from scara_gym.benchmark import protocol  # noqa: E402


def test_budgets_double_from_the_first_and_end_at_the_last_checkpoint():
    steps = [250_000 * k for k in range(1, 41)]
    assert learning_curves.budgets(steps) == [250_000, 500_000, 1_000_000, 2_000_000, 4_000_000, 8_000_000,
                                             10_000_000]
    assert learning_curves.budgets([100, 200, 300, 400], first=100) == [100, 200, 400]
    assert learning_curves.budgets([100, 200, 300], first=100) == [100, 200, 300]
    assert learning_curves.budgets([]) == []
    # the first budget defaults to the first checkpoint (the off-policy runs keep one every 62.5k steps)
    assert learning_curves.budgets([62_500 * k for k in range(1, 17)]) == [62_500, 125_000, 250_000, 500_000,
                                                                          1_000_000]


def _row(success, time):
    row = {"collision_rate": 0.0}
    for band in learning_curves.BAND_NAMES:
        row[f"success_{band}"], row[f"time_iqm_{band}"] = success, time
    return row


def test_the_plateau_rule_reads_the_last_doubling_per_doubling():
    budgets = [1, 2, 4, 8]
    flat = learning_curves.plateau([_row(0.5, 2.0), _row(0.9, 1.5), _row(0.95, 1.21), _row(0.955, 1.2)], budgets)
    assert flat["from"] == 4 and flat["to"] == 8 and flat["plateau"] is True
    rising = learning_curves.plateau([_row(0.5, 2.0), _row(0.9, 1.5), _row(0.93, 1.2), _row(0.95, 1.2)], budgets)
    assert rising["plateau"] is False and rising["change_per_doubling"]["success_1e-3"] == pytest.approx(0.02)
    # the rule reads from the largest budget at most half the last (2 for 7), per doubling (log2 3.5 of them)
    partial = learning_curves.plateau([_row(0.5, 2.0), _row(0.9, 1.6), _row(0.9, 1.6)], [2, 4, 7])
    assert partial["from"] == 2 and partial["change_per_doubling"]["success_1e-3"] == pytest.approx(0.4 / np.log2(3.5))
    assert learning_curves.plateau([_row(0.5, 2.0)], [5])["plateau"] is None


def test_a_point_scores_each_band_and_counts_a_miss_at_the_time_limit():
    result = {"collisions": np.array([0, 1, 0, 0])}
    for band in learning_curves.BAND_NAMES:
        reached, times = (("success", "reach_time") if band == "1e-3" else (f"success_{band}", f"reach_time_{band}"))
        result[reached] = np.array([True, False, True, True])
        result[times] = np.array([1.0, np.nan, 1.2, 1.4])
    row = learning_curves.point(result)
    assert row["collision_rate"] == 0.25 and row["success_1e-3"] == 0.75
    assert row["time_iqm_1e-2"] == pytest.approx(np.mean([1.2, 1.4]))  # IQM of 1.0, 1.2, 1.4, 3.0


def test_every_learning_curve_run_names_a_protocol_condition_and_has_its_block_on_the_latest_id():
    curve_runs = [r for r in RUNS.values() if "learning-curve" in r.tags]
    assert {r.trained_on for r in curve_runs} == {"c11-starts", "random-targets", "random-shifts"}
    for run in curve_runs:
        hyper = hyperparams_of(run.name, protocol.ENV_ID)
        # issue 58: 1e7 steps for PPO, 1e6 for the off-policy algorithms; at least 5 budgets that double
        assert hyper["n_timesteps"] >= (1e7 if run.sb3_algorithm == "ppo" else 1e6)
        assert len(learning_curves.budgets(list(range(hyper["checkpoint_freq"], hyper["n_timesteps"] + 1, hyper["checkpoint_freq"])))) >= 5
        if run.trained_on == "c11-starts":  # its starts come by reset options: trained with randomize_start
            assert hyper["env_kwargs"] == {"randomize_start": True}
        else:
            assert hyper["env_kwargs"] == protocol.CONDITIONS[run.trained_on].env_kwargs
    with pytest.raises(ValueError, match="trained_on must be one of the protocol's conditions"):
        RunSpec("x", "sb3", "x", tags=frozenset({"learning-curve"}), trained_on="moon")
    with pytest.raises(ValueError, match="'learning-curve' tag and a trained_on condition go together"):
        RunSpec("x", "sb3", "x", tags=frozenset({"learning-curve"}))


def test_a_tiny_run_gives_a_curve_with_its_raw_episodes(tmp_path, capsys):
    hyper = hyperparams_of("ppo-c11-starts", protocol.ENV_ID)
    hyper.update(n_envs=2, n_steps=64, batch_size=64, n_epochs=1, checkpoint_freq=128, snapshot_freq=10_000,
                 eval_freq=10_000, eval_episodes=1)
    folder = tmp_path / "runs" / protocol.ENV_ID / "pd" / "ppo-c11-starts" / "seed0"
    train_run("ppo-c11-starts", folder, 0, total_timesteps=512, hyperparams=hyper)
    folders = learning_curves.run_folders("ppo-c11-starts", tmp_path / "runs")
    assert folders == [folder]
    data = learning_curves.learning_curve("ppo-c11-starts", folders, episodes=2, out=tmp_path / "out",
                                           first_budget=128)
    assert data["budgets"] == [128, 256, 512] and data["env_id"] == protocol.ENV_ID
    assert data["scored_on"].startswith("c11-starts (tuning): 2 episodes from seed ")
    assert int(data["scored_on"].rsplit(" ", 1)[1]) == protocol.tuning("c11-starts").seed  # never evaluation seeds
    assert [r["steps"] for r in data["seeds"]["0"]] == [128, 256, 512]
    assert all(len(data["raw"]["0"][str(b)]["success"]) == 2 for b in data["budgets"])
    written = json.loads((tmp_path / "out" / "ppo-c11-starts.json").read_text())
    assert written["budgets"] == data["budgets"] and (tmp_path / "out" / "ppo-c11-starts.png").stat().st_size > 0
    with pytest.raises(ValueError, match="is not a learning-curve run"):
        learning_curves.learning_curve("ppo", folders, episodes=2)
    # a curve written before keeps the seeds this call does not score again (another sitting's seed 7)
    published = json.loads((tmp_path / "out" / "ppo-c11-starts.json").read_text())
    published["seeds"]["7"] = [dict(row, **{"success_1e-3": 1.0 - row["success_1e-3"]}) for row in data["seeds"]["0"]]
    published["raw"]["7"] = published["raw"].pop("0")
    published["seeds"].pop("0")
    (tmp_path / "before.json").write_text(json.dumps(published))
    merged = learning_curves.learning_curve("ppo-c11-starts", folders, episodes=2, first_budget=128,
                                             merge=tmp_path / "before.json")
    assert sorted(merged["seeds"]) == ["0", "7"] and merged["seeds"]["0"] == data["seeds"]["0"]
    assert merged["raw"]["7"] == published["raw"]["7"]
    assert [m["success_1e-3"] for m in merged["mean"]] == [0.5, 0.5, 0.5]  # the mean of s and 1 - s
    published["episodes"] = 3
    (tmp_path / "other.json").write_text(json.dumps(published))
    with pytest.raises(ValueError, match="its episodes is 3, not 2"):
        learning_curves.learning_curve("ppo-c11-starts", folders, episodes=2, first_budget=128,
                                       merge=tmp_path / "other.json")
