"""The real-time MPC's search under the learned baselines' rule: the published configuration first,
every finished trial kept at once, a stopped search going on where it stopped, the rule's choice."""

import json

import gymnasium as gym
import numpy as np
import pytest

from agents.experiments import mpc_search
from agents.policies.mpc import MPCConfig, MPCPolicy
from scara_gym.model.checks import UserError


def fake_score(calls):
    """A score that prefers short horizons and small wall margins; raises on the call numbered in ``calls["fail"]``."""
    def score(point, episodes, mode):
        calls["n"] += 1
        if calls["n"] == calls.get("fail"):
            raise KeyboardInterrupt
        value = 1.0 - point["horizon"] / 100 - point["wall_margin"]
        return {"objective": value, "collision_rate": 0.0, "success_1e-3": 1.0, "success_1e-2": 1.0,
                "success_5e-2": 1.0, "step_time_median": 0.004, "step_time_p95": 0.008}
    return score


def test_the_first_trial_is_the_published_configuration_and_the_best_is_the_highest_objective(tmp_path):
    record = mpc_search.tune_mpc(tmp_path, trials=6, episodes=3, score=fake_score({"n": 0}))
    assert record["trials"][0]["point"] == mpc_search.DEFAULT_POINT
    assert mpc_search.mpc_config(mpc_search.DEFAULT_POINT) == MPCConfig(weights=tuple(mpc_search.default_weights()))
    objectives = [t["figures"]["objective"] for t in record["trials"]]
    assert record["trials_run"] == 6 and record["best"] == objectives.index(max(objectives))
    best = json.loads((tmp_path / "best.json").read_text())["mpc"]
    assert best["horizon"] == record["trials"][record["best"]]["point"]["horizon"]
    assert MPCConfig(**{**best, "weights": tuple(best["weights"])})  # a valid configuration
    assert len((tmp_path / "trials.jsonl").read_text().splitlines()) == 6
    assert "6 of 6 trials run" in (tmp_path / "search.md").read_text()


def test_a_stopped_search_goes_on_from_the_trials_it_finished(tmp_path):
    calls = {"n": 0, "fail": 4}
    with pytest.raises(KeyboardInterrupt):
        mpc_search.tune_mpc(tmp_path, trials=6, episodes=3, score=fake_score(calls))
    kept = (tmp_path / "trials.jsonl").read_text().splitlines()
    assert len(kept) == 3 and not (tmp_path / "search.json").exists()
    with (tmp_path / "trials.jsonl").open("a") as f:
        f.write('{"setup": {"episo')  # a line torn by a crash: left out
    calls = {"n": 0}
    record = mpc_search.tune_mpc(tmp_path, trials=6, episodes=3, score=fake_score(calls))
    assert calls["n"] == 3 and record["trials_run"] == 6  # only the missing trials ran
    assert mpc_search._read_trials(tmp_path / "trials.jsonl") == record["trials"]  # the torn line is gone
    assert [json.dumps(t["point"]) for t in record["trials"][:3]] == [json.dumps(json.loads(k)["point"]) for k in kept]
    with pytest.raises(UserError, match="another setup"):
        mpc_search.tune_mpc(tmp_path, trials=7, episodes=4, score=fake_score({"n": 0}))


def test_one_trial_scores_the_real_time_mpc_on_tuning_episodes():
    figures = mpc_search.score_point(mpc_search.DEFAULT_POINT, episodes=1)
    assert figures["success_1e-3"] == 1.0 and figures["collision_rate"] == 0.0
    assert 0.9 < figures["objective"] < 1.0 and 0 < figures["step_time_median"] <= figures["step_time_p95"]


def test_the_heuristics_distance_is_searched_the_same_way_from_its_published_distance(tmp_path):
    seen = []

    def score(point, episodes, mode):  # a score that prefers distances near 0.09 m
        seen.append((point["distance"], episodes, mode))
        return {"objective": 1.0 - abs(point["distance"] - 0.09), "collision_rate": 0.0, "success_1e-3": 1.0,
                "success_1e-2": 1.0, "success_5e-2": 1.0, "step_time_median": 1e-5, "step_time_p95": 2e-5}

    controller = mpc_search.heuristic_controller("continue", score=score, published=0.0664)
    record = mpc_search.tune_controller(controller, tmp_path, trials=5, episodes=2, mode="pd")
    assert seen[0] == (0.0664, 2, "pd") and len(seen) == 5 and record["policy"] == "dec-continue"
    assert all(0.02 <= d <= 0.2 for d, _, _ in seen)
    best = json.loads((tmp_path / "best.json").read_text())
    assert best == {"dec-continue": {"distance": record["trials"][record["best"]]["point"]["distance"]}}
    with pytest.raises(UserError, match="another setup"):  # an MPC search is not resumed from it
        mpc_search.tune_mpc(tmp_path, trials=6, episodes=2, mode="pd", score=fake_score({"n": 0}))


def test_one_trial_scores_the_heuristic_on_tuning_episodes():
    controller = mpc_search.heuristic_controller("continue", published=0.08)
    figures = controller.score({"distance": 0.08}, 2, "pd")
    assert 0.0 <= figures["success_1e-3"] <= 1.0 and -0.031 <= figures["objective"] <= 1.0
    assert 0 < figures["step_time_median"] <= figures["step_time_p95"]


def test_the_default_weights_are_the_ones_the_mpc_uses_when_given_none():
    pytest.importorskip("casadi")
    env = gym.make(mpc_search.ENV_ID, control_mode="voltage")
    np.testing.assert_array_equal(MPCPolicy(env, MPCConfig()).weights, mpc_search.default_weights())
