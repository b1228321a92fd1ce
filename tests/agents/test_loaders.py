"""agents.algorithms.loaders: one table from a policy spec's kind to its loader; a run folder, bare
or as run:DIR, loads with the trainer it records, and the trust checks stay those of its trainer."""

import json

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401
from agents import files
from agents.algorithms.loaders import LOADERS, TRAINERS, load_policy, parse_spec, run_spec, shipped_model
from agents.experiments.evaluation import make_policy
from scara_gym.model.checks import UserError
from scara_gym.wrappers import Shield


def test_every_spec_kind_has_its_loader_and_the_old_name_is_the_one_function():
    assert {"pd", "dec-continue", "dec-restart", "optimal", "mpc", "mpc-rti", "run", "ppo", "sb3", "torchppo", "bc", "zoo",
            "shield"} == set(LOADERS)
    assert set(TRAINERS.values()) <= set(LOADERS)
    assert make_policy is load_policy
    assert parse_spec("pd") == ("pd", "") and parse_spec("dec-continue:0.05") == ("dec-continue", "0.05")
    assert parse_spec("shield:torchppo:a/b") == ("shield", "torchppo:a/b")
    assert run_spec("a/b", shield=True) == "shield:run:a/b"
    with pytest.raises(UserError, match="unknown policy 'nowhere/at-all'"):
        parse_spec("nowhere/at-all")
    assert shipped_model("pd") is None and shipped_model("ppo:ppo_pd").name == "ppo_pd"


@pytest.fixture(scope="module")
def torch_run(tmp_path_factory):
    pytest.importorskip("torch")
    from agents.algorithms.torch_ppo import Config, train

    out = tmp_path_factory.mktemp("loaders") / "torch-run"
    train(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16, hidden_size=8,
                 out=str(out)))
    return out


def test_a_bare_folder_and_run_dir_load_the_trainer_the_folder_records(torch_run, tmp_path, monkeypatch):
    from agents.algorithms.torch_ppo import TorchPPOPolicy

    env = gym.make("Scara-C11-v1")
    obs, _ = env.reset(seed=0)
    named = load_policy(f"torchppo:{torch_run}", env)
    for spec in (str(torch_run), f"run:{torch_run}"):
        policy = load_policy(spec, env)
        assert isinstance(policy, TorchPPOPolicy) and np.array_equal(policy(obs), named(obs))
    shielded = load_policy(f"shield:{torch_run}", env)
    assert isinstance(shielded, Shield) and isinstance(shielded.policy, TorchPPOPolicy)
    monkeypatch.chdir(torch_run.parent)
    assert isinstance(load_policy(torch_run.name, env), TorchPPOPolicy)  # a relative bare folder
    # a folder that records no trainer, and no folder at all
    with pytest.raises(FileNotFoundError, match="not a run folder"):
        load_policy(f"run:{tmp_path}", env)
    with pytest.raises(FileNotFoundError, match="no run folder"):
        load_policy(f"run:{tmp_path / 'missing'}", env)
    with pytest.raises(UserError, match="run policies are given as run:RUN_DIR"):
        load_policy("run:", env)


def test_a_run_without_run_json_is_loaded_by_the_algo_its_config_names(torch_run, tmp_path):
    import shutil

    from agents.algorithms.torch_ppo import TorchPPOPolicy

    old = tmp_path / "published"
    shutil.copytree(torch_run, old)
    (old / files.RUN_RECORD).unlink()  # as published runs are: model and history only
    assert files.recorded_run(old)["trainer"] == "torch-ppo"
    assert isinstance(load_policy(str(old), gym.make("Scara-C11-v1")), TorchPPOPolicy)
    config = json.loads((old / "config.json").read_text())
    (old / "config.json").write_text(json.dumps({**config, "algo": "bc"}))
    assert files.recorded_run(old)["trainer"] == "bc"  # a behaviour-cloning run's config says algo bc


def test_a_run_folder_of_sb3_pickle_loads_only_when_trusted_as_with_sb3_dir(tmp_path, monkeypatch):
    pytest.importorskip("stable_baselines3")
    import shutil
    from pathlib import Path

    from agents.algorithms.sb3.policy import SB3Policy

    monkeypatch.delenv(files.TRUST_ENV, raising=False)
    env = gym.make("Scara-C11-v0")
    shipped = Path(files.__file__).resolve().parent / "models" / "ppo_pd"
    assert isinstance(load_policy(f"run:{shipped}", env), SB3Policy)  # shipped: vouched for
    copy = tmp_path / "from-elsewhere"
    shutil.copytree(shipped, copy)
    (copy / "NOTES").write_text("copied\n")
    (copy / files.DIGESTS).write_text((copy / files.DIGESTS).read_text()
                                      + f"{files.file_digest(copy / 'NOTES')}  NOTES\n")
    for spec in (str(copy), f"run:{copy}", f"sb3:{copy}"):
        with pytest.raises(files.UntrustedFolder, match="pass --trust"):
            load_policy(spec, env)
    monkeypatch.setenv(files.TRUST_ENV, "1")
    assert isinstance(load_policy(str(copy), env), SB3Policy)


def test_rl_zoos_yaml_is_read_safely_its_ordered_dict_as_a_dict(tmp_path):
    """RL Zoo's config.yml and args.yml carry Python's OrderedDict tag: read as the pairs it holds;
    any other Python tag (which YAML's full loader would call) is refused, and nothing runs."""
    pytest.importorskip("yaml")
    from agents.algorithms.sb3.zoo import zoo_run, zoo_yaml
    from scara_gym.model.checks import UserError

    text = (b"!!python/object/apply:collections.OrderedDict\n- - - gamma\n    - 0.99\n"
            b"  - - env_kwargs\n    - randomize_start: true\n")
    assert zoo_yaml(tmp_path / "config.yml", text) == {"gamma": 0.99, "env_kwargs": {"randomize_start": True}}
    marker = tmp_path / "ran"
    evil = f"!!python/object/apply:os.system ['touch {marker}']\n".encode()
    with pytest.raises(UserError, match="not a YAML file RL Zoo writes"):
        zoo_yaml(tmp_path / "args.yml", evil)
    assert not marker.exists()
    with pytest.raises(UserError, match="not a YAML file RL Zoo writes"):
        zoo_yaml(tmp_path / "args.yml", b"- a list\n")
    with pytest.raises(FileNotFoundError, match="not a folder RL Zoo writes"):
        zoo_run(tmp_path)
