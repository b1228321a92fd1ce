"""DAgger (agents.algorithms.dagger): the expert's labels, the residual maps' inverses, a tiny run
loaded as a policy, and a resumed run equal to an uninterrupted one."""

import json

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("casadi")

from agents.algorithms import dagger  # noqa: E402
from agents.algorithms.dagger_config import DAggerConfig  # noqa: E402
from agents.algorithms.loaders import load_policy  # noqa: E402
from agents.files import load_torch  # noqa: E402
from scara_gym.benchmark.protocol import get_condition  # noqa: E402
from scara_gym.model.checks import UserError  # noqa: E402
from scara_gym.wrappers import ResidualOnPD  # noqa: E402

TINY = dict(conditions=("c11-starts",), iterations=2, episodes_per_iteration=2, tuning_episodes=2,
            steps_per_iteration=50, hidden_size=16, patience=5)


def test_the_residual_on_pd_maps_voltages_back_to_the_outputs_that_give_them():
    env = get_condition("c11-starts").make_env("voltage")
    obs, _ = env.reset(seed=3)
    mapping = ResidualOnPD(env, (2.0, 2.0, 2.0))
    r = np.random.default_rng(0).uniform(-1, 1, (1, 3))
    voltages = mapping(obs, r)
    unclipped = np.abs(voltages) < 1.0
    np.testing.assert_allclose(mapping.agent_actions(obs, voltages)[unclipped], r[unclipped], atol=1e-12)
    assert np.all(np.abs(mapping.agent_actions(obs, np.array([[1.0, -1.0, 1.0]]))) <= 1.0)


@pytest.mark.parametrize("field, value, message", [
    ("conditions", ("c12",), "conditions"), ("control_mode", "torque", "control_mode"),
    ("beta", 1.5, "beta"), ("residual_on", "pd", "goes with control_mode"), ("iterations", 0, "iterations")])
def test_a_bad_setting_is_refused_by_name(field, value, message):
    with pytest.raises(UserError, match=message):
        DAggerConfig(**{field: value})


@pytest.mark.slow
def test_a_tiny_run_is_a_policy_and_a_resumed_run_equals_an_uninterrupted_one(tmp_path, monkeypatch):
    whole = dagger.train(DAggerConfig(**TINY, out=str(tmp_path / "whole")))
    summary = json.loads((tmp_path / "whole" / "summary.json").read_text())
    assert [i["iteration"] for i in summary["iterations"]] == [0, 1]
    assert summary["iterations"][0]["expert_share"] == 1.0  # iteration 0: the expert alone
    assert summary["iterations"][1]["transitions"] > summary["iterations"][0]["transitions"]
    assert whole["best_iteration"] in (0, 1) and whole["algo"] == "dagger"
    env = get_condition("c11-starts").make_env("pd")
    policy = load_policy(f"run:{tmp_path / 'whole'}", env)  # the folder's trainer: the cloned MLP
    obs, _ = env.reset(seed=5)
    action = policy(obs)
    assert action.shape == (3,) and np.all(np.abs(action) <= 1.0)

    real_collect = dagger.collect

    def dies_at_the_second_iteration(config, iteration, *args):
        if iteration == 1:
            raise KeyboardInterrupt
        return real_collect(config, iteration, *args)

    monkeypatch.setattr(dagger, "collect", dies_at_the_second_iteration)
    with pytest.raises(KeyboardInterrupt):
        dagger.train(DAggerConfig(**TINY, out=str(tmp_path / "resumed")))
    monkeypatch.setattr(dagger, "collect", real_collect)
    dagger.train(DAggerConfig(**TINY, out=str(tmp_path / "resumed")), resume=True)
    a, b = (load_torch(tmp_path / run / "model.pt")["state_dict"] for run in ("whole", "resumed"))
    assert all(np.array_equal(a[k].numpy(), b[k].numpy()) for k in a)
    resumed = json.loads((tmp_path / "resumed" / "summary.json").read_text())
    assert [i["gap"] for i in resumed["iterations"]] == [i["gap"] for i in summary["iterations"]]


def test_the_distilled_runs_are_registered_and_train_sets_their_fields(tmp_path, capsys):
    from agents.cli import run
    from agents.experiments.registry import RUNS, RunSpec, tagged

    assert set(tagged("distilled")) == {name for name, s in RUNS.items() if s.trainer == "dagger"} != set()
    with pytest.raises(UserError, match="'dagger' trainer and the 'distilled' tag"):
        RunSpec("x", "dagger", "x")
    for argv, message in ((["dagger-mpc-rti-voltage", "--set", "iterations=1"], "goes with control_mode 'voltage'"),
                          (["dagger-mpc-rti", "--set", "conditions=c11-starts,c12"], "conditions")):
        with pytest.raises(SystemExit) as exit_:
            run(["train", *argv, "--out", str(tmp_path / "run")])
        assert exit_.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()  # refused before any folder is made
