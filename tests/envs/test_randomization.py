"""Domain randomization: parameters drawn per episode (scara_gym.envs.randomization)."""

import inspect
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding
from gymnasium.utils.env_checker import check_env

import scara_gym  # noqa: F401
from scara_gym import DEFAULT_PARAMS
from scara_gym.envs import OBSERVATION_LAYOUT, ScaraEnv, randomization
from scara_gym.envs.randomization import PRESETS, ParameterRanges, leaf_value
from scara_gym.envs.task import draw_target
from scara_gym.model.dynamics import tip_position


def test_the_module_table_is_the_presets():
    rows = re.findall(r"^\| (physics|wall) \| ([^|]+) \| nominal ([x+]) \[?(-?[\d.]+), (-?[\d.]+)\]",
                      inspect.getdoc(randomization), flags=re.M)
    documented = {}
    for preset, paths, sign, low, high in rows:
        for path in paths.split(","):
            path = path.strip()
            kind = "factor" if sign == "x" else "offset"
            expand = [path.replace(".i.", f".{i}.") for i in range(3)] if ".i." in path else [path]
            for p in expand:
                documented[p] = (preset, kind, float(low), float(high))
    presets = {path: (name, kind, low, high) for name in ("physics", "wall") for path, kind, low, high in PRESETS[name]}
    assert documented == presets
    assert [row[0] for row in PRESETS["all"]] == [row[0] for row in PRESETS["physics"] + PRESETS["wall"]]


def test_the_card_states_the_preset_ranges():
    card = " ".join(inspect.getdoc(ScaraEnv).split())
    for path, kind, low, high in PRESETS["all"]:
        text = f"x [{low:g}, {high:g}]" if kind == "factor" else f"+- {high:g} m"
        assert text in card, (path, text)


def test_draws_stay_in_their_ranges_differ_across_resets_and_follow_the_seed():
    env = gym.make("Scara-C11-v1", randomize_params="all")
    ranges = ParameterRanges.preset("all", DEFAULT_PARAMS).ranges
    draws = [env.reset(seed=s)[1]["params"] for s in range(20)]
    for draw in draws:
        assert set(draw) == set(ranges)
        for path, value in draw.items():
            low, high = ranges[path]
            assert low <= value <= high, path
    for path in ranges:
        assert len({d[path] for d in draws}) == len(draws), path  # every reset a new value
    again = gym.make("Scara-C11-v1", randomize_params="all")
    assert [again.reset(seed=s)[1]["params"] for s in range(20)] == draws
    # unseeded resets continue the stream: no two episodes share parameters
    env.reset(seed=3)
    assert env.reset()[1]["params"] != env.reset()[1]["params"]


def test_the_drawn_parameters_are_the_physics_of_the_episode():
    """An episode under a draw is bit for bit the episode of an env built with those values."""
    env = ScaraEnv(randomize_params="all", exact_switches=True, rtol=1e-6, atol=1e-8)
    _, info = env.reset(seed=11)
    drawn = info["params"]
    assert env.episode_params == DEFAULT_PARAMS.replace(drawn)
    for path, value in drawn.items():
        assert leaf_value(env.episode_params, path) == value
    fixed = ScaraEnv(params=drawn, exact_switches=True, rtol=1e-6, atol=1e-8)
    fixed.reset(seed=11)
    action = env.setpoint_to_action([2.0, 2.0, 0.3]).astype(np.float32)
    for _ in range(60):
        a, b = env.step(action), fixed.step(action)
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1] == b[1] and a[2] == b[2]
        if a[2]:
            break
    # the next episode restores nothing it should not: the nominal physics after an override
    _, info = env.reset(seed=12, options={"params": {"arm.load_mass": 1.7}})
    assert info["params"]["arm.load_mass"] == 1.7 and env.episode_params.arm.load_mass == 1.7
    plain = ScaraEnv()
    plain.reset(seed=0, options={"params": {"axes.0.current_limit": 5.0}})
    assert plain._task.robot_params["current_limit"][0, 0] == 5.0
    _, info = plain.reset(seed=0)
    assert "params" not in info and plain.episode_params is plain.params
    assert plain._task.robot_params[0] == plain._task.nominal_record


def test_an_override_in_options_wins_over_the_draw():
    env = gym.make("Scara-C11-v1", randomize_params="all")
    drawn = env.reset(seed=5)[1]["params"]
    _, info = env.reset(seed=5, options={"params": {"arm.load_mass": 0.9, "obstacle.x_position": 0.36}})
    assert info["params"]["arm.load_mass"] == 0.9 != drawn["arm.load_mass"]
    assert info["params"]["obstacle.x_position"] == 0.36
    assert {k: v for k, v in info["params"].items() if k not in ("arm.load_mass", "obstacle.x_position")} == \
        {k: v for k, v in drawn.items() if k not in ("arm.load_mass", "obstacle.x_position")}
    assert env.unwrapped.episode_params.obstacle.x_position == 0.36


def test_randomized_targets_clear_the_drawn_wall():
    env = ScaraEnv(randomize_params="wall", randomize_target=True)
    for seed in range(30):
        obs, info = env.reset(seed=seed)
        obstacle = env.episode_params.obstacle
        assert info["target"][2] >= obstacle.height + 0.02
        assert obs[OBSERVATION_LAYOUT["tip_x"]] > obstacle.x_position  # the start's tip is on the far side
        x_target, _, _ = tip_position(*info["target"], env.episode_params.to_record())
        assert x_target < obstacle.x_position - obstacle.critical_distance - 0.02


def test_observations_stay_inside_the_space_built_around_the_range_ends():
    env = ScaraEnv(control_mode="voltage", randomize_params="all", collision="penalty")
    high = env.observation_space.high
    assert high[6] == np.float32(1.1 * 6.64) and high[14] == np.float32(0.7 + 0.39)
    rng = np.random.default_rng(0)
    for seed in range(4):
        obs, _ = env.reset(seed=seed)
        for _ in range(120):
            obs, _, terminated, _, _ = env.step(rng.choice([-1.0, 1.0], size=3).astype(np.float32))
            assert env.observation_space.contains(obs)
            if terminated:
                break


def test_the_vector_env_draws_as_the_single_env():
    n, seed = 3, 40
    venv = gym.make_vec("Scara-C11-v1", num_envs=n, vectorization_mode="vector_entry_point",
                        randomize_params="all")
    obs, info = venv.reset(seed=seed)
    action = np.tile(ScaraEnv().setpoint_to_action([2.0, 2.0, 0.3]), (n, 1))
    steps = [venv.step(action)[0] for _ in range(30)]
    for i in range(n):
        env = gym.make("Scara-C11-v1", randomize_params="all")
        single_obs, single_info = env.reset(seed=seed + i)
        np.testing.assert_array_equal(single_obs, obs[i])
        assert {k: v[i] for k, v in info["params"].items()} == single_info["params"]
        for k in range(30):
            np.testing.assert_array_equal(env.step(action[i].astype(np.float32))[0], steps[k][i])


def test_pd_actions_of_a_batch_use_each_robots_parameters():
    venv = gym.make_vec("Scara-C11-v1", num_envs=4, vectorization_mode="vector_entry_point",
                        control_mode="voltage", randomize_params={"axes.0.p_gain": (200.0, 2000.0)})
    obs, info = venv.reset(seed=0)
    gains = info["params"]["axes.0.p_gain"]
    assert len(set(gains.tolist())) == 4
    setpoint = np.array([0.01, 0.0, 0.0])  # small: the PD law stays unsaturated on axis 0
    batch = venv.unwrapped.pd_action(obs, setpoint)
    for i in range(4):
        single = ScaraEnv(control_mode="voltage", params={"axes.0.p_gain": gains[i]})
        expected = single.pd_action(obs[i], setpoint)
        np.testing.assert_allclose(batch[i], expected, rtol=1e-12)
    assert len(set(batch[:, 0].tolist())) == 4


def test_randomized_envs_pass_the_checkers():
    env = gym.make("Scara-C11-v1", randomize_params="all", randomize_target=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    assert [str(w.message) for w in caught] == []
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(ScaraEnv(randomize_params=True), warn=True)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("value, error, match", [
    ("heavy", ValueError, "randomize_params must be False, True, one of"),
    (1, TypeError, "randomize_params must be"),
    ({}, TypeError, "randomize_params must be"),
    ({"arm.load_mas": (0.1, 1.0)}, ValueError, "unknown parameter 'arm.load_mas'"),
    ({"obstacle.dec": (0.1, 1.0)}, ValueError, "'obstacle.dec' cannot vary per episode"),
    ({"task.accuracy": (0.1, 1.0)}, ValueError, "cannot vary per episode"),
    ({"axes": (0.1, 1.0)}, ValueError, "not a scalar"),
    ({"arm.load_mass": (1.0, 0.5)}, ValueError, r"low <= high"),
    ({"arm.load_mass": 1.0}, TypeError, r"must be \(low, high\)"),
    ({"arm.load_mass": (-1.0, 1.0)}, ValueError, r"ArmParams.load_mass must be a finite number in \[0.001, 1000\]"),
    ({"arm.load_mass": (0.1, float("nan"))}, ValueError, "finite number"),
])
def test_bad_ranges_are_named(value, error, match):
    with pytest.raises(error, match=match):
        ScaraEnv(randomize_params=value)


@pytest.mark.parametrize("options, error, match", [
    ({"params": {"axes.0.current_limit": 100.0}}, ValueError, "exceeds the observation bound"),
    ({"params": {"obstacle.x_position": 0.5}}, ValueError, "exceeds the observation bound"),
    ({"params": {"arm.load_mass": -1.0}}, ValueError, "load_mass must be a finite number"),
    ({"params": {"arm.nothing": 1.0}}, ValueError, "unknown parameter"),
    ({"params": {"obstacle.dec": 0.1}}, ValueError, "cannot vary per episode"),
    ({"params": {"arm.load_mass": "1"}}, TypeError, "finite number"),
    ({"params": [1.0]}, TypeError, "dict of dotted paths"),
    ({"param": {}}, ValueError, "unknown reset options"),
])
def test_bad_overrides_are_named_and_change_nothing(options, error, match):
    env = ScaraEnv(randomize_params="all")
    obs, info = env.reset(seed=2)
    before = (env._task.robot_params.copy(), env.state, env.episode_params)
    with pytest.raises(error, match=match):
        env.reset(seed=3, options=options)
    assert env._task.robot_params == before[0]
    np.testing.assert_array_equal(env.state, before[1])
    assert env.episode_params is before[2]


def test_without_randomization_nothing_is_drawn():
    """An env without randomize_params draws its target first, as before randomization existed."""
    env = ScaraEnv(randomize_target=True)
    for seed in range(5):
        _, info = env.reset(seed=seed)
        rng, _ = seeding.np_random(seed)
        expected = draw_target(rng, env._task.default_start, env.params, obstacle=True)
        np.testing.assert_array_equal(info["target"], expected)
        assert "params" not in info


@pytest.mark.parametrize("env_id", sorted(set(scara_gym.ENV_VARIANTS) - set(scara_gym.GOAL_ENV_IDS)))
def test_each_variant_passes_the_checkers_and_is_deterministic_for_a_seed(env_id):
    """(The goal env's checkers and determinism: test_goal.py.)"""
    env = gym.make(gym.spec(env_id))  # the frozen -v0 ids too, on purpose: from the spec
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
        pytest.importorskip("stable_baselines3.common.env_checker").check_env(env.unwrapped, warn=True)
    assert [str(w.message) for w in caught] == []

    def rollout(seed):
        env = gym.make(env_id, randomize_target=True)
        rng = np.random.default_rng(seed)
        out = []
        for episode in range(3):
            obs, info = env.reset(seed=seed if episode == 0 else None)
            out += [obs, np.array(list(info["params"].values()))]
            for _ in range(40):
                obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
                out += [obs, np.array([reward])]
                if terminated or truncated:
                    break
        return out

    first, second, other = rollout(7), rollout(7), rollout(8)
    assert all(np.array_equal(a, b) for a, b in zip(first, second, strict=True))
    assert not np.array_equal(first[1], other[1])  # another seed, other parameters
