"""Scara-C11-Goal-v1: the goal API (compute_reward and friends), its card, its vector env."""

import inspect
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import scara_gym
from scara_gym.envs.config import FIELDS
from scara_gym.envs.goal import GOAL_OBSERVATION_NAMES, ScaraGoalEnv

GOAL = "Scara-C11-Goal-v1"


def transitions(reward_type: str, count: int = 1000):
    """(achieved, desired, infos, rewards, terminated, truncated, base events) of `count` steps:
    PD moves straight at the goal, which hit the wall, and the same without the wall, which
    reach it; random set-points in between."""
    rng = np.random.default_rng(0)
    envs = [gym.make(GOAL, reward_type=reward_type), gym.make(GOAL, reward_type=reward_type, obstacle=False)]
    rows = []
    episode = 0
    while len(rows) < count:
        env = envs[episode % 2]
        obs, _ = env.reset(seed=episode)
        straight = env.unwrapped.setpoint_to_action(obs["desired_goal"])
        for _ in range(300):
            action = straight if rng.random() < 0.95 else rng.uniform(-1, 1, 3)
            obs, reward, terminated, truncated, info = env.step(action.astype(np.float32))
            reached = bool(env.unwrapped._task.outcomes["reached"][0])
            rows.append((obs["achieved_goal"], obs["desired_goal"], info, reward, terminated, truncated, reached))
            if terminated or truncated:
                break
        episode += 1
    achieved, desired, infos, rewards, terms, truncs, reached = zip(*rows[:count])
    return (np.array(achieved), np.array(desired), np.array(infos, dtype=object), np.array(rewards),
            np.array(terms), np.array(truncs), np.array(reached))


def test_the_mixed_reward_is_the_sparse_one_plus_the_dense_one():
    achieved, desired, infos, rewards, *_ = transitions("mixed", count=400)
    sparse, dense = (gym.make(GOAL, reward_type=kind, collision_penalty=0.0).unwrapped.compute_reward(
        achieved, desired, infos) for kind in ("sparse", "dense"))
    goal_terms = np.array([i["reward_terms"]["goal"] for i in infos])
    np.testing.assert_array_equal(goal_terms, sparse + dense)
    reached = np.array([i["is_success"] for i in infos])
    assert reached.any() and (goal_terms[reached] > -1).all() and (goal_terms[~reached] <= -1).all()


@pytest.mark.parametrize("reward_type", ["sparse", "dense", "mixed"])
def test_compute_functions_over_a_batch_equal_the_steps(reward_type):
    env = gym.make(GOAL, reward_type=reward_type).unwrapped
    achieved, desired, infos, rewards, terminated, truncated, reached = transitions(reward_type)
    assert achieved.shape == (1000, 3) and achieved.dtype == np.float32
    successes = np.array([i["is_success"] for i in infos])
    collisions = np.array([i["cost"] for i in infos]) > 0
    assert successes.sum() >= 3 and collisions.sum() >= 3  # both kinds of episode end are in the batch
    np.testing.assert_array_equal(env.compute_reward(achieved, desired, infos), rewards)
    np.testing.assert_array_equal(env.compute_terminated(achieved, desired, infos), terminated)
    np.testing.assert_array_equal(env.compute_truncated(achieved, desired, infos), truncated)
    # a dict of arrays (the vector env's info) and one transition at a time say the same
    as_arrays = {"cost": np.array([i["cost"] for i in infos])}
    np.testing.assert_array_equal(env.compute_reward(achieved, desired, as_arrays), rewards)
    assert [env.compute_reward(a, d, i) for a, d, i in zip(achieved[:50], desired[:50], infos[:50])] == \
        rewards[:50].tolist()
    # the named terms sum to the reward, and the located C11 event always counts as success
    assert all(sum(i["reward_terms"].values()) == r for i, r in zip(infos, rewards))
    assert np.all(successes[reached])


def test_relabeled_goals_are_rewarded_by_the_goal_test():
    env = ScaraGoalEnv()
    achieved = np.random.default_rng(1).uniform(-1, 1, (100, 3)).astype(np.float32)
    info = np.array([{"cost": 0.0}] * 100, dtype=object)
    np.testing.assert_array_equal(env.compute_reward(achieved, achieved, info), np.zeros(100))
    np.testing.assert_array_equal(env.compute_reward(achieved, achieved + 0.01, info), -np.ones(100))
    hit = np.array([{"cost": 1.0}] * 100, dtype=object)
    np.testing.assert_array_equal(env.compute_reward(achieved, achieved, hit), -50.0 * np.ones(100))
    assert env.compute_terminated(achieved, achieved + 0.01, hit).all()
    with pytest.raises(KeyError, match="copy_info_dict"):
        env.compute_reward(achieved, achieved, np.array([{}] * 100, dtype=object))


def test_the_goal_env_passes_the_checkers_and_is_deterministic():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(gym.make(GOAL).unwrapped, skip_render_check=True)
        pytest.importorskip("stable_baselines3.common.env_checker").check_env(ScaraGoalEnv(), warn=True)
    assert [str(w.message) for w in caught] == []

    def rollout(seed):
        env = gym.make(GOAL, reward_type="dense")
        rng = np.random.default_rng(seed)
        obs, _ = env.reset(seed=seed)
        out = [np.concatenate(list(obs.values()))]
        for _ in range(60):
            obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
            out.append(np.concatenate([*obs.values(), [reward, terminated]]))
            if terminated or truncated:
                obs, _ = env.reset()
        return np.concatenate(out)

    np.testing.assert_array_equal(rollout(3), rollout(3))
    assert not np.array_equal(rollout(3), rollout(4))


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "SameStep"])
def test_each_robot_of_the_goal_vector_env_is_the_single_env(autoreset_mode):
    n, seed = 3, 7
    venv = gym.make_vec(GOAL, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=autoreset_mode,
                        obstacle=False, observation_noise={"rate": 0.01})
    assert venv.single_observation_space == ScaraGoalEnv(obstacle=False, observation_noise={"rate": 0.01}).observation_space
    obs, _ = venv.reset(seed=seed)
    singles = [gym.make(GOAL, obstacle=False, observation_noise={"rate": 0.01}) for _ in range(n)]
    single_obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    pending = [False] * n
    actions = np.array([env.unwrapped.setpoint_to_action(o["desired_goal"]) for env, o in zip(singles, single_obs)])
    ended = 0
    for _ in range(200):
        for key in obs:
            np.testing.assert_array_equal(obs[key], np.array([o[key] for o in single_obs]))
        obs, reward, terminated, truncated, info = venv.step(actions)
        for i, env in enumerate(singles):
            if pending[i]:  # NextStep: this step reset robot i
                single_obs[i], _ = env.reset()
                pending[i] = False
                assert reward[i] == 0.0 and not terminated[i]
                continue
            o, r, te, tr, single_info = env.step(actions[i])
            assert (r, te, tr) == (reward[i], terminated[i], truncated[i])
            assert single_info["is_success"] == info["is_success"][i]
            if te or tr:
                ended += 1
                if autoreset_mode == "SameStep":
                    for key in o:
                        np.testing.assert_array_equal(info["final_obs"][key][i], o[key])
                    o, _ = env.reset()
                else:
                    pending[i] = True
            single_obs[i] = o
    assert ended >= n  # every robot reached its goal at least once


def test_the_registered_arguments_are_the_class_defaults():
    registered = scara_gym.ENV_VARIANTS[GOAL]
    assert registered == {name: getattr(ScaraGoalEnv.config_defaults, name) for name in registered}


def test_the_card_matches_the_spaces_and_arguments():
    doc = inspect.getdoc(ScaraGoalEnv)
    env = ScaraGoalEnv()
    rows = {r[0]: r for r in re.findall(r"^\| (\w+) \| \((\d+),\) \| (.*?) \|$", doc, flags=re.M)}
    assert set(rows) == set(env.observation_space.spaces)
    for key, space in env.observation_space.spaces.items():
        assert space.shape == (int(rows[key][1]),) and space.dtype == np.float32
    listed = re.search(r'"observation" holds (.*?), with', doc, flags=re.S).group(1)
    assert [n.strip() for n in listed.split(",")] == list(GOAL_OBSERVATION_NAMES)
    arguments = doc[doc.index("## Arguments"):doc.index("## Version history")]
    documented = dict(re.findall(r"^- (\w+) \(([^)]*)\)", arguments, flags=re.M))
    own = {n: p.default for n, p in inspect.signature(ScaraGoalEnv.__init__).parameters.items()
           if n not in ("self", "overrides")}
    configured = {name: getattr(ScaraGoalEnv.config_defaults, name) for name in FIELDS}
    assert list(documented) == [*list(own)[:-1], *configured, "render_mode"]
    for name, default in {**own, **configured}.items():
        assert documented[name] == repr(default).replace("'", '"'), name
    for reward_type in ("sparse", "dense", "mixed"):
        assert f"| {reward_type} |" in doc
    with pytest.raises(ValueError, match="reward_type must be one of 'sparse', 'dense'"):
        ScaraGoalEnv(reward_type="shaped")
    with pytest.raises(ValueError, match=r"collision_penalty must be a finite number in \[0, 1e\+06\]"):
        ScaraGoalEnv(collision_penalty=-1.0)


def test_a_looser_goal_tolerance_ends_episodes_earlier_and_relabels_with_it():
    """goal_tolerance: the goal test's tol (the C11 acc by default); PD straight at the goal
    without the wall passes within 0.05 before it reaches acc."""
    ends = {}
    for tolerance in (None, 0.05):
        env = gym.make(GOAL, obstacle=False, goal_tolerance=tolerance)
        obs, _ = env.reset(seed=2)
        action = env.unwrapped.setpoint_to_action(obs["desired_goal"]).astype(np.float32)
        for step in range(1, 301):  # noqa: B007  (the step it ends on is kept)
            obs, reward, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        gap = np.abs(obs["achieved_goal"].astype(np.float64) - obs["desired_goal"]).max()
        assert terminated and info["is_success"] and reward == 0.0
        assert gap < (0.05 if tolerance else 0.001) + 1e-6
        assert env.unwrapped.compute_reward(obs["achieved_goal"], obs["desired_goal"], info) == 0.0
        ends[tolerance] = (step, gap)
    assert ends[0.05][0] < ends[None][0] and ends[0.05][1] > 0.001  # ended on the looser test, earlier
    loose = ScaraGoalEnv(goal_tolerance=0.05)
    near = np.zeros((2, 3), dtype=np.float32)
    np.testing.assert_array_equal(loose.compute_reward(near, near + np.float32(0.04), None), [0.0, 0.0])
    np.testing.assert_array_equal(loose.compute_reward(near, near + np.float32(0.06), None), [-1.0, -1.0])
    for bad in (0.0005, 2.0, float("nan")):
        with pytest.raises(ValueError, match=r"goal_tolerance must be a finite number in \[0.001, 1\]"):
            ScaraGoalEnv(goal_tolerance=bad)


def test_compute_reward_refuses_goals_and_infos_that_do_not_fit():
    env = ScaraGoalEnv()
    achieved = np.zeros((4, 3))
    infos = np.array([{"cost": 0.0}] * 4, dtype=object)
    bad = [
        (achieved, achieved + np.nan, infos, "desired_goal must be finite"),
        (np.full((4, 3), np.inf), achieved, infos, "achieved_goal must be finite"),
        (achieved, np.zeros((4, 2)), infos, r"one shape \(\.\.\., 3\).*\(4, 3\) and \(4, 2\)"),
        (achieved, np.zeros(4), infos, "one shape"),
        (achieved, achieved, [{"cost": 0.0}], r"one step's info per pair of goals, \(4,\); got info for \(1,\)"),
        (achieved, achieved, {"cost": np.zeros(3)}, r"got info for \(3,\)"),
        (achieved, achieved, {"cost": np.array([0.0, np.nan, 0.0, 0.0])}, "finite numbers >= 0"),
        (achieved, achieved, {"cost": -np.ones(4)}, "finite numbers >= 0"),
        ([["a", "b", "c"]], [["a", "b", "c"]], None, "arrays of numbers"),
    ]
    for a, d, info, says in bad:
        for compute in (env.compute_reward, env.compute_terminated):
            with pytest.raises(ValueError, match=says):
                compute(a, d, info)
    with pytest.raises(ValueError, match="one shape"):
        env.compute_truncated(achieved, np.zeros((3, 3)), infos)
    np.testing.assert_array_equal(env.compute_reward(achieved, achieved, infos), np.zeros(4))  # fit: as before


def test_complex_goals_are_refused_not_cast():
    env = gym.make("Scara-C11-Goal-v0").unwrapped
    goal = np.array([2.0, 2.0, 0.3])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a cast that discards the imaginary part warns: that must not happen either
        with pytest.raises(ValueError, match="achieved_goal and desired_goal must be arrays of real numbers"):
            env.compute_reward(goal + 1j, goal, {})
