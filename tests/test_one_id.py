"""One environment id for everything: every public entry point runs the latest id's integration
arguments unless told otherwise, and nothing outside the tests filters Gymnasium's note that an
id is out of date."""

import json
import re
import subprocess
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import scara_gym
from scara_gym import LATEST_ENV_ID, LATEST_INTEGRATION

ROOT = Path(__file__).resolve().parents[1]


def integration_of(task) -> dict:
    return {name: getattr(task, name) for name in LATEST_INTEGRATION}


def test_the_latest_integration_is_the_latest_ids():
    assert LATEST_INTEGRATION == scara_gym.ENV_VERSIONS[LATEST_ENV_ID] == {
        "rtol": 1e-7, "atol": 1e-9, "exact_switches": True}
    assert LATEST_ENV_ID in scara_gym.LATEST_IDS
    assert all(scara_gym.ENV_KWARGS[env_id].items() >= LATEST_INTEGRATION.items() for env_id in scara_gym.LATEST_IDS)
    assert not hasattr(scara_gym, "ENV_ID") and not hasattr(scara_gym, "TRAINING_ENV_ID")


def test_every_environment_class_defaults_to_the_latest_integration():
    from scara_gym.envs import ScaraEnv
    from scara_gym.envs.goal import ScaraGoalEnv, ScaraGoalVectorEnv
    from scara_gym.envs.task import ScaraTask
    from scara_gym.envs.vector import ScaraVectorEnv

    for make in (ScaraEnv, ScaraGoalEnv, ScaraTask, lambda: ScaraVectorEnv(num_envs=2),
                 lambda: ScaraGoalVectorEnv(num_envs=2)):
        env = make()
        assert integration_of(env if isinstance(env, ScaraTask) else env._task) == LATEST_INTEGRATION, make


def test_make_and_make_vec_of_the_latest_id():
    assert integration_of(gym.make(LATEST_ENV_ID).unwrapped._task) == LATEST_INTEGRATION
    venv = gym.make_vec(LATEST_ENV_ID, num_envs=2, vectorization_mode="vector_entry_point")
    assert integration_of(venv._task) == LATEST_INTEGRATION


def test_the_sb3_adapter_takes_an_id_and_defaults_to_the_latest():
    pytest.importorskip("stable_baselines3")
    from scara_gym.integrations.sb3 import SB3VecEnv

    assert integration_of(SB3VecEnv(num_envs=2, control_mode="pd").venv._task) == LATEST_INTEGRATION
    older = SB3VecEnv(num_envs=2, env_id="Scara-C11-v1")
    assert integration_of(older.venv._task) == scara_gym.ENV_VERSIONS["Scara-C11-v1"]
    randomized = SB3VecEnv(num_envs=2, env_id="Scara-C11-RandomWall-v1")
    assert randomized.venv._task.randomization and integration_of(randomized.venv._task) == LATEST_INTEGRATION
    with pytest.raises(ValueError, match="env_id must be one of"):
        SB3VecEnv(num_envs=2, env_id="Scara-C11-v9")


def test_the_protocol_runs_on_the_latest_id():
    from scara_gym.benchmark import protocol

    assert protocol.ENV_ID == LATEST_ENV_ID
    env = protocol.get_condition("c11").make_env()
    assert env.spec.id == LATEST_ENV_ID and integration_of(env.unwrapped._task) == LATEST_INTEGRATION
    seen = []

    class Still:
        def reset(self):
            pass

        def __call__(self, obs):
            return np.zeros(3, dtype=np.float32)

    def policy_factory(env):
        seen.append(integration_of(env.unwrapped._task))
        return Still()

    protocol.evaluate("c11-starts", policy_factory, episodes=1)
    assert seen == [LATEST_INTEGRATION]


def test_every_agents_subcommand_defaults_to_the_latest_id():
    pytest.importorskip("stable_baselines3")
    from agents.algorithms.torch_ppo_config import Config
    from agents.cli import build_parser
    from agents.experiments import runs
    from agents.policies.heuristic import ENV_ID as heuristic_env_id

    subcommands = build_parser()._subparsers._group_actions[0].choices
    with_env_id = {name for name, parser in subcommands.items()
                   if any(action.dest == "env_id" for action in parser._actions)}
    assert {"evaluate", "train", "torch-ppo", "campaign", "sweep"} <= with_env_id
    for name in with_env_id:
        default = next(a.default for a in subcommands[name]._actions if a.dest == "env_id")
        if name == "torch-ppo":  # its flags default to None: the Config's own defaults apply
            default = Config().env_id if default is None else default
        assert default == LATEST_ENV_ID, name
    # the rest evaluate on the protocol's id (above); training and the heuristic's search default to it
    assert Config().env_id == LATEST_ENV_ID and heuristic_env_id == LATEST_ENV_ID
    import inspect
    for function in (runs.train_run, runs.campaign, runs.hyperparams_of):
        assert inspect.signature(function).parameters["env_id"].default == LATEST_ENV_ID, function


def test_no_filter_of_gymnasiums_out_of_date_note_outside_the_tests():
    """Gymnasium says an id is out of date: the project never silences that for its users; a
    tool that measures a frozen id on purpose builds it from its spec (gym.make(gym.spec(id)))."""
    files = subprocess.run(["git", "ls-files", "*.py", "*.toml", "*.cfg", "*.ini"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.split()
    pattern = re.compile(r"filterwarnings|simplefilter\(\s*[\"']ignore|out of date")
    found = []
    for name in files:
        if name.startswith("tests/"):
            continue
        for number, line in enumerate((ROOT / name).read_text().splitlines(), 1):
            if pattern.search(line) and "DeprecationWarning" in line or re.search(r"filterwarnings.*out of date", line):
                found.append(f"{name}:{number}: {line.strip()}")
            elif re.search(r"(filterwarnings|simplefilter)\(\s*[\"']ignore[\"']\s*\)", line):
                found.append(f"{name}:{number}: {line.strip()}")  # a blanket filter silences it too
    assert found == []


def test_the_published_results_name_the_latest_id():
    """The comparison and the robustness curves are published on the latest id, every comparison
    entry naming it (runs trained on an older id are scored on it as they are), each made by a
    product command that the file records."""
    results = ROOT / "docs" / "results"
    comparison = json.loads((results / "comparison.json").read_text())
    assert comparison["env_id"] == LATEST_ENV_ID
    assert comparison["policies"] and {entry["env_id"] for entry in comparison["policies"]} == {LATEST_ENV_ID}
    assert comparison["command"].startswith("scara-agents compare ")
    curves = json.loads((results / "curves.json").read_text())
    assert curves["env_id"] == LATEST_ENV_ID and curves["command"].startswith("scara-agents curves ")


def test_the_published_datasets_summary_is_the_latest_version():
    """docs/results/datasets.json lists the datasets of the version on the latest id."""
    from agents.experiments.datasets import DATASETS

    rows = json.loads((ROOT / "docs" / "results" / "datasets.json").read_text())["datasets"]
    assert rows and all(DATASETS[row["name"]].env_id == LATEST_ENV_ID for row in rows)
