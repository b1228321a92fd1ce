"""The envs' declared state surface (scara_gym.envs.surface): snapshots round-trip bit for bit,
the set-point maps invert each other, the vector env's per-robot methods are the single env's,
and no agent or wrapper reaches into the task object behind them."""

import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401

ROOT = Path(__file__).resolve().parents[2]
ENV_ID = "Scara-C11-v2"


def _vector(num_envs: int, **kwargs):
    return gym.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("kwargs", [dict(control_mode="pd"),
                                    dict(control_mode="voltage", randomize_target=True, action_delay=1)])
def test_a_restored_snapshot_takes_the_same_steps_bit_for_bit(kwargs):
    env = gym.make(ENV_ID, **kwargs)
    actions = np.random.default_rng(3).uniform(-1.0, 1.0, (40, 3)).astype(np.float32)
    env.reset(seed=1)
    for action in actions[:15]:
        env.step(action)
    saved = env.unwrapped.snapshot()
    first = [env.step(action)[:4] for action in actions[15:]]
    env.unwrapped.restore(saved)
    assert env.unwrapped.snapshot()["t"] == saved["t"]
    again = [env.step(action)[:4] for action in actions[15:]]
    for (obs, reward, terminated, truncated), (obs2, reward2, terminated2, truncated2) in zip(first, again):
        assert obs.tobytes() == obs2.tobytes() and reward == reward2
        assert (terminated, truncated) == (terminated2, truncated2)


def test_restore_after_the_episode_ended_goes_on_from_the_snapshot():
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=0)
    saved = env.snapshot()
    target_action = env.setpoint_to_action(env.target).astype(np.float32)
    ended = False
    for _ in range(300):
        if env.step(target_action)[2]:
            ended = True
            break
    assert ended  # plain PD on the target collides with the wall: the episode ends
    env.restore(saved)
    np.testing.assert_array_equal(env.state, saved["x"])
    env.step(target_action)  # no "call reset() before step()"


def test_the_vector_envs_snapshot_restore_round_trips_one_robot():
    venv = _vector(3, control_mode="voltage").unwrapped
    venv.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (20, 3, 3))
    for a in actions[:8]:
        venv.step(a)
    saved, seen = venv.snapshot(1), venv.noise_free_observation(1)
    first = [venv.step(a)[0][1].copy() for a in actions[8:]]
    venv.restore(1, saved)
    assert venv.noise_free_observation(1).tobytes() == seen.tobytes()
    again = [venv.step(a)[0][1].copy() for a in actions[8:]]
    assert all(x.tobytes() == y.tobytes() for x, y in zip(first, again))
    with pytest.raises(ValueError, match="robot must be an integer in"):
        venv.snapshot(3)


@pytest.mark.parametrize("control_mode", ["pd", "voltage"])
def test_the_set_point_maps_invert_each_other_on_the_action_box(control_mode):
    env = gym.make(ENV_ID, control_mode=control_mode).unwrapped
    obs, _ = env.reset(seed=0)
    actions = np.random.default_rng(1).uniform(-0.99, 0.99, (200, 3))
    # the "pd" maps: set-point <-> action
    setpoints = env.action_to_setpoint(actions)
    np.testing.assert_allclose(np.array([env.setpoint_to_action(s) for s in setpoints]), actions, atol=1e-12)
    # the PD law and its inverse on an observation: action -> set-point -> action
    batch = np.tile(obs.astype(np.float64), (len(actions), 1))
    np.testing.assert_allclose(env.pd_action(batch, env.pd_setpoint(batch, actions)), actions, atol=1e-9)
    # setpoint_action is the mode's map: the clipped "pd" action, or the PD law's voltages
    expected = np.clip(actions, -1, 1) if control_mode == "pd" else env.pd_action(batch, setpoints)
    np.testing.assert_allclose(env.setpoint_action(batch, setpoints), expected, atol=1e-12)


def test_the_vector_envs_per_robot_methods_are_the_single_envs_with_the_same_seed():
    kwargs = dict(control_mode="voltage", randomize_target=True, randomize_params="physics")
    venv = _vector(3, **kwargs).unwrapped
    obs, _ = venv.reset(seed=10)
    actions = np.random.default_rng(2).uniform(-1.0, 1.0, (5, 3, 3))
    for a in actions:
        obs, *_ = venv.step(a)
    setpoint = np.array([1.0, 1.5, 0.25])
    batch = venv.setpoint_action(obs, setpoint)
    for i in range(3):
        env = gym.make(ENV_ID, **kwargs).unwrapped
        single_obs, _ = env.reset(seed=10 + i)
        for a in actions:
            single_obs, *_ = env.step(a[i])
        np.testing.assert_array_equal(venv.noise_free_observation(i), env.noise_free_observation())
        np.testing.assert_array_equal(venv.targets[i], env.target)
        assert venv.episode_params[i] == env.episode_params
        mine, theirs = venv.snapshot(i), env.snapshot()
        assert mine.keys() == theirs.keys()
        assert mine.pop("params") == theirs.pop("params")
        for key in mine:
            np.testing.assert_array_equal(mine[key], theirs[key])
        np.testing.assert_array_equal(batch[i], env.setpoint_action(single_obs, setpoint))
        np.testing.assert_array_equal(venv.setpoint_action(obs[i], setpoint, robot=i),
                                      env.setpoint_action(single_obs, setpoint))
        np.testing.assert_array_equal(venv.pd_setpoint(obs, batch)[i], env.pd_setpoint(single_obs, batch[i]))
        assert venv.config == env.config and venv.control_dt == env.control_dt


def test_reset_robot_starts_one_robots_episode_between_steps():
    venv = _vector(2, autoreset_mode="Disabled").unwrapped
    venv.reset(seed=0)
    for _ in range(3):
        venv.step(np.zeros((2, 3)))
    before = venv.snapshot(1)
    info = venv.reset_robot(0, {"target": [1.8, 2.1, 0.3]}, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(info["target"], [1.8, 2.1, 0.3])
    np.testing.assert_array_equal(venv.targets[0], [1.8, 2.1, 0.3])
    assert venv.snapshot(0)["t"] == 0.0 and venv.snapshot(1)["t"] == before["t"]
    venv.step(np.zeros((2, 3)))


ATTRIBUTE = re.compile(r"(\w+)\.task\b")
NOT_THE_TASK_OBJECT = {"envs"}
"""``scara_gym.envs.task`` (the module); and ``*params.task`` (the model's task parameters)"""
SPEC_TASK = {"agents/experiments/datasets.py": {"self", "spec"}}
"""a dataset spec's task name"""


def test_no_agent_or_wrapper_reaches_into_the_task_object():
    found = []
    for folder in ("agents", "scara_gym/wrappers", "scara_gym/integrations"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            name = path.relative_to(ROOT).as_posix()
            allowed = NOT_THE_TASK_OBJECT | SPEC_TASK.get(name, set())
            for number, line in enumerate(path.read_text().splitlines(), start=1):
                code = line.split("#", 1)[0]
                if "._task" in code or any(
                        m.group(1) not in allowed and not m.group(1).lower().endswith("params")
                        for m in ATTRIBUTE.finditer(code)):
                    found.append(f"{name}:{number}: {line.strip()}")
    assert not found, "reaching into the task object:\n" + "\n".join(found)


def test_the_envs_have_no_public_task_attribute():
    assert not hasattr(gym.make(ENV_ID).unwrapped, "task")
    assert not hasattr(_vector(2).unwrapped, "task")
