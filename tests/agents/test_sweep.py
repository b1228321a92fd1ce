"""agents.experiments.sweep: seeds x grids on a local Ray runtime, results in the comparison's format."""

import json

import numpy as np
import pytest

pytest.importorskip("ray")

from agents.experiments import sweep  # noqa: E402


def test_grid_parsing_and_tags():
    grid = sweep.parse_grid(["learning_rate=0.0003,0.001", "ent_coef=auto", "use_sde=true"])
    assert grid == {"learning_rate": [0.0003, 0.001], "ent_coef": ["auto"], "use_sde": [True]}
    points = sweep.grid_points({"a": [1, 2], "b": [3]})
    assert points == [{"a": 1, "b": 3}, {"a": 2, "b": 3}]
    assert sweep.tag({"b": 3, "a": 1}) == "a=1_b=3" and sweep.tag({}) == "default"
    with pytest.raises(ValueError, match="--grid takes NAME=V1,V2"):
        sweep.parse_grid(["learning_rate"])


def test_a_two_trial_local_sweep_reports_the_trial_that_trains_and_the_one_that_fails(tmp_path):
    """Two grid points on a local Ray runtime: one trains and is evaluated; the other fails
    (SB3 refuses batch_size 1, which the grid check lets pass), is retried once, and is reported, not lost."""
    entries = sweep.run_sweep("ppo", "Scara-C11-v1", "pd", seeds=[0],
                              grid={"n_steps": [64], "batch_size": [64, 1], "n_epochs": [1], "n_envs": [1]},
                              out=tmp_path, episodes=2, total_timesteps=64, max_failures=1, num_cpus=2)
    assert [e["hyperparameters"]["batch_size"] for e in entries] == [64]
    good = entries[0]
    assert good["seeds"] == [0] and good["episodes"] == 2 and good["kind"] == "learned"
    assert set(good) >= {"name", "algorithm", "success_rate", "collision_rate", "time_iqm", "time_ci",
                         "energy_mean", "condition", "per_seed"}
    run = tmp_path / "runs" / "batch_size=64_n_envs=1_n_epochs=1_n_steps=64" / "seed0"
    assert (run / "model.zip").exists() and json.loads((run / "config.json").read_text())["total_timesteps"] == 64
    with np.load(run / "evaluation.npz") as data:
        assert data["success"].shape == (2,)
    written = json.loads((tmp_path / "sweep.json").read_text())
    assert written["policies"] == json.loads(json.dumps(entries))
    (failure,) = written["failed"]
    assert failure["point"]["batch_size"] == 1 and failure["attempts"] == 2
    assert "batch_size" in failure["error"]
    table = (tmp_path / "sweep.md").read_text()
    assert "| ppo batch_size=64_n_envs=1_n_epochs=1_n_steps=64 | learned | pd | 0 | 2 |" in table
    assert "Failed trials" in table and "(2 attempts)" in table


def test_unknown_grid_names_are_refused_before_any_trial(tmp_path):
    with pytest.raises(ValueError, match=r"--grid names \['learning_rat'\]"):
        sweep.run_sweep("sac", "Scara-C11-v1", "pd", seeds=[0], grid={"learning_rat": [0.1]}, out=tmp_path)


def test_a_run_trained_for_a_looser_goal_is_evaluated_in_its_task_and_the_benchmarks(tmp_path):
    """The HER block trains Scara-C11-Goal-v0 with goal_tolerance 0.05: its trial evaluates the
    run there and at the benchmark's own goal test, and the sweep lists both."""
    from agents.experiments.runs import hyperparams_of

    assert sweep.task_kwargs(hyperparams_of("sac", "Scara-C11-Goal-v0")) == {"goal_tolerance": 0.05}
    assert sweep.task_kwargs(hyperparams_of("ppo", "Scara-C11-v1")) == {}
    tiny = {"learning_starts": 310, "eval_freq": 400, "eval_episodes": 1, "snapshot_freq": 400, "buffer_size": 2000}
    result = sweep.train_and_evaluate("sac", "Scara-C11-Goal-v0", "pd", 0, tiny, tmp_path / "run", "random-targets",
                                      episodes=2, total_timesteps=500)
    assert set(result) == {"train_seconds", *sweep.EPISODE_ARRAYS, *("benchmark_" + k for k in sweep.EPISODE_ARRAYS)}
    assert result["success"].shape == result["benchmark_success"].shape == (2,)
    with pytest.raises(ValueError, match="the condition 'random-targets' sets \\['randomize_target'\\] itself"):
        from scara_gym.benchmark.protocol import CONDITIONS
        CONDITIONS["random-targets"].make_env("pd", "Scara-C11-v1", randomize_target=False)


def test_the_command_line_passes_its_concurrency_limit_to_ray(tmp_path, monkeypatch):
    seen = {}

    def fake_sweep(*args, **kwargs):
        seen.update(kwargs)
        (tmp_path / "sweep.md").write_text("table")
        return []

    monkeypatch.setattr(sweep, "run_sweep", fake_sweep)
    from agents.cli import run

    run(["sweep", "--run", "ppo", "--seeds", "0", "--out", str(tmp_path), "--max-concurrent", "1"])
    assert seen["max_concurrent"] == 1
    run(["sweep", "--run", "ppo", "--seeds", "0", "--out", str(tmp_path)])
    assert seen["max_concurrent"] is None


def test_a_torch_ppo_trial_trains_and_is_evaluated(tmp_path):
    """Every registered run can be swept: a torch PPO grid point names Config fields."""
    tiny = {"num_envs": 2, "num_steps": 8, "num_minibatches": 1, "update_epochs": 1, "ent_coef": 0.01}
    result = sweep.train_and_evaluate("torch-ppo", "Scara-C11-v1", "pd", 0, tiny, tmp_path / "run", "c11",
                                      episodes=2, total_timesteps=16)
    assert result["success"].shape == (2,) and result["train_seconds"] > 0
    assert json.loads((tmp_path / "run" / "config.json").read_text())["ent_coef"] == 0.01
    with pytest.raises(ValueError, match=r"--grid names \['ent_cof'\]"):
        sweep.point_hyperparams("torch-ppo", "Scara-C11-v1", "pd", {"ent_cof": 0.0})


@pytest.mark.parametrize("point", [{"learning_rate": "../../escape"}, {"learning_rate": "a/b"},
                                   {"../x": 1}, {"learning_rate": ".hidden"}, {"learning_rate": "x y"}])
def test_grid_points_that_are_not_plain_names_are_refused_before_any_folder(point, tmp_path):
    with pytest.raises(ValueError, match="not a plain name and value"):
        sweep.run_sweep("ppo", "Scara-C11-v1", "pd", seeds=[0], grid={k: [v] for k, v in point.items()}, out=tmp_path)
    assert list(tmp_path.iterdir()) == []
    assert sweep.tag({"learning_rate": 1e-05, "use_sde": True}) == "learning_rate=1e-05_use_sde=True"


def test_a_shipped_model_is_named_plainly():
    pytest.importorskip("stable_baselines3")
    from agents.algorithms.sb3.policy import SHIPPED_MODELS, resolve_model

    assert resolve_model("ppo_pd") == SHIPPED_MODELS / "ppo_pd"
    for name in ("../models/ppo_pd", "ppo_pd/../ppo_pd", "../../agents/models/ppo_pd"):
        with pytest.raises(FileNotFoundError, match="shipped model name"):
            resolve_model(name)


def test_a_local_runtime_binds_to_loopback_and_stops_on_sigterm(tmp_path, monkeypatch):
    import os
    import signal

    import ray
    from ray import tune

    calls = {}
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", lambda **kwargs: calls.setdefault("init", kwargs))
    monkeypatch.setattr(ray, "shutdown", lambda: calls.setdefault("shutdown", True))

    class Terminated:  # the driver gets SIGTERM while the trials run
        def __init__(self, *args, **kwargs):
            pass

        def fit(self):
            calls["handler"] = signal.getsignal(signal.SIGTERM)
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(tune, "Tuner", Terminated)
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt, match="signal 15"):
        sweep.run_sweep("ppo", "Scara-C11-v1", "pd", [0], {}, tmp_path, episodes=1, num_cpus=1)
    assert calls["init"]["_node_ip_address"] == "127.0.0.1" and calls["init"]["include_dashboard"] is False
    assert calls["handler"] is sweep._interrupt and calls["shutdown"] is True
    assert signal.getsignal(signal.SIGTERM) is before  # restored
    calls.clear()
    with pytest.raises(KeyboardInterrupt):  # an existing cluster: joined, not bound or stopped here
        sweep.run_sweep("ppo", "Scara-C11-v1", "pd", [0], {}, tmp_path, episodes=1, address="ray://head:10001")
    assert "_node_ip_address" not in calls["init"] and calls["init"]["address"] == "ray://head:10001"


def test_a_folder_in_the_working_folder_does_not_shadow_a_shipped_model(tmp_path, monkeypatch):
    pytest.importorskip("stable_baselines3")
    import shutil

    from agents.algorithms.sb3.policy import SHIPPED_MODELS, resolve_model

    monkeypatch.chdir(tmp_path)
    shutil.copytree(SHIPPED_MODELS / "ppo_voltage", tmp_path / "ppo_pd")  # another model under the shipped name
    assert resolve_model("ppo_pd") == SHIPPED_MODELS / "ppo_pd"  # the name is the shipped model's
    assert resolve_model("./ppo_pd").resolve() == tmp_path / "ppo_pd"  # a path is a path
