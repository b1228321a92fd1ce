"""scara_gym.benchmark.protocol: named conditions with their own seeds, drawn as documented, and
the one evaluation function."""

import numpy as np
import pytest

import scara_gym  # noqa: F401
from scara_gym import DEFAULT_PARAMS
from scara_gym.benchmark import protocol
from scara_gym.benchmark.episodes import run_episodes
from scara_gym.envs.task import TARGET_HIGH, TARGET_LOW


class Hold:
    """A deterministic policy that passes the wall: hold axes 1 and 2 until the tool is above the
    wall, then go to the target."""

    name = "climb first"

    def __init__(self, env):
        self.env = env.unwrapped

    def reset(self):
        self.start = None

    def __call__(self, obs):
        target = obs[:3] + obs[9:12]
        if self.start is None:
            self.start = obs[:3].copy()
        if obs[15] < 0.01:  # height_margin
            target = np.array([self.start[0], self.start[1], target[2]])
        return self.env.setpoint_action(obs, target)


def test_every_condition_has_its_own_seeds_apart_from_tuning_and_training():
    bands = []
    for condition in protocol.CONDITIONS.values():
        seeds = condition.seeds(condition.episodes)
        assert seeds[0] == condition.seed >= protocol.EVALUATION_SEED
        bands.append(range(condition.seed, condition.seed + protocol.SEED_BAND))
        tuning = protocol.tuning(condition.name)
        assert protocol.TUNING_SEED <= tuning.seed < protocol.EVALUATION_SEED
        assert tuning.env_kwargs == condition.env_kwargs and tuning.params == condition.params
        assert not set(tuning.seeds(50)) & set(condition.seeds(50))
    starts = sorted(b.start for b in bands)
    assert all(b - a >= protocol.SEED_BAND for a, b in zip(starts, starts[1:]))  # disjoint bands
    assert protocol.TRAINING_SEED_LIMIT <= protocol.TUNING_SEED


def test_the_start_region_is_drawn_per_seed_as_documented():
    condition = protocol.CONDITIONS["c11-starts"]
    starts = np.array([condition.options(s)["start"] for s in condition.seeds(200)])
    low, high = protocol.START_OFFSETS
    assert np.all(starts >= low) and np.all(starts <= high)
    assert len({tuple(s) for s in starts}) == 200
    assert np.all(starts.max(axis=0) - starts.min(axis=0) > 0.8 * (high - low))  # the whole region
    assert condition.options(condition.seed) == condition.options(condition.seed)  # reproducible
    assert protocol.CONDITIONS["c11"].options(0) is None
    assert [c.name for c in protocol.CONDITIONS.values() if c.deterministic] == ["c11"]


def test_conditions_build_the_environment_they_describe():
    load = protocol.CONDITIONS["load-x2"].make_env()
    assert load.unwrapped.params.arm.load_mass == 2 * DEFAULT_PARAMS.arm.load_mass
    shifts = protocol.CONDITIONS["random-shifts"].make_env()
    drawn = [shifts.reset(seed=s)[1]["params"]["arm.load_mass"] for s in range(5)]
    assert len(set(drawn)) == 5
    targets = protocol.CONDITIONS["random-targets"].make_env()
    target = targets.reset(seed=3)[1]["target"]
    assert np.all(target >= TARGET_LOW) and np.all(target <= TARGET_HIGH)
    delayed = protocol.CONDITIONS["delay-1"].make_env().unwrapped._task
    assert delayed.sim_to_real.action_delay == 1
    noisy = protocol.CONDITIONS["sensor-noise"].make_env().unwrapped._task
    assert noisy.sim_to_real.sensor_std.tolist() == [1e-3] * 3 + [0.01] * 3 + [0.02] * 3
    assert protocol.shift_condition("axes.*.resistance", 1.2).params == protocol.CONDITIONS["resistance+20"].params
    assert protocol.noise_condition(5).make_env().unwrapped._task.sim_to_real.sensor_std.tolist() == \
        protocol.CONDITIONS["sensor-noise-x5"].make_env().unwrapped._task.sim_to_real.sensor_std.tolist()
    with pytest.raises(ValueError, match="unknown condition 'c12'; the protocol's conditions are"):
        protocol.get_condition("c12")
    with pytest.raises(ValueError, match="sets \\['randomize_target'\\] itself"):
        protocol.CONDITIONS["random-targets"].make_env(randomize_target=False)


def test_a_condition_without_draws_runs_its_one_episode_once():
    """run_episodes(identical=True): the first episode stands for all where the first two are
    the same (a deterministic policy, nothing drawn), and every episode runs where they differ."""
    c11 = protocol.CONDITIONS["c11"]
    env = c11.make_env()
    seeds = list(range(4))
    full, short = (run_episodes(env, Hold(env), seeds, identical=same) for same in (False, True))
    for key in ("success", "collisions", "reach_time", "energy"):
        assert np.array_equal(full[key], short[key], equal_nan=True), key
    drawn = protocol.evaluate("random-targets", Hold, episodes=4)
    assert len(set(drawn["energy"].tolist())) == 4  # other targets: every episode ran
    assert drawn["condition"] == "random-targets"
    assert drawn["seeds"].tolist() == protocol.CONDITIONS["random-targets"].seeds(4)


def test_evaluate_gives_each_episode_its_drawn_start():
    starts = protocol.evaluate("c11-starts", Hold, episodes=3, record=3)
    condition = protocol.CONDITIONS["c11-starts"]
    env = condition.make_env()
    for seed, trace in zip(condition.seeds(3), starts["traces"]):
        _, info = env.reset(seed=seed, options=condition.options(seed))
        tip = env.unwrapped.noise_free_observation()[12:14]
        assert np.allclose(trace[0, 1:3], tip)  # the trace starts at the drawn start's tip


def test_a_condition_reruns_on_other_seeds_and_records_itself():
    import json

    condition = protocol.CONDITIONS["c11-starts"]
    other = condition.with_seed(1000)
    assert other.seeds(2) == [1000, 1001] and other.env_kwargs == condition.env_kwargs
    assert other.options(1000) != condition.options(condition.seed)
    record = protocol.protocol_record(["c11", "c11-starts", "sensor-noise"])
    assert record["c11-starts"]["random_starts"] and record["c11"]["start_offsets"] is None
    assert record["sensor-noise"]["env_kwargs"] == {"sensor_noise": protocol.SENSOR_NOISE}
    json.dumps(record)


def test_evaluate_takes_a_plain_callable_and_refuses_bad_arguments_by_name():
    """The docstring's promise: a policy is a callable obs -> action (reset() is called where it has one)."""
    result = protocol.evaluate("c11", lambda env: (lambda obs: np.zeros(3)), episodes=2)
    assert len(result["success"]) == 2
    with pytest.raises(ValueError, match=r"episodes must be an integer in \[1, .*\], got 0"):
        protocol.tuning("c11", episodes=0)
    with pytest.raises(ValueError, match="record must be an integer >= 0, got -1"):
        protocol.evaluate("c11", lambda env: (lambda obs: np.zeros(3)), episodes=1, record=-1)
    with pytest.raises(TypeError, match="env_kwargs must be a mapping of environment arguments or None, got 'x'"):
        protocol.evaluate("c11", lambda env: (lambda obs: np.zeros(3)), episodes=1, env_kwargs="x")


def test_the_corners_condition_puts_every_parameter_at_an_end_of_its_range():
    """corners (issue 53): every parameter of the "all" ranges at its low or high end, the ends drawn
    per episode from the condition's own seeds, beside random-shifts (the same ranges, drawn inside)."""
    from scara_gym.envs.randomization import ParameterRanges

    corners = protocol.CONDITIONS["corners"]
    ranges = ParameterRanges.preset("all", DEFAULT_PARAMS).ranges
    assert corners.seed == protocol.EVALUATION_SEED + 12 * protocol.SEED_BAND and not corners.deterministic
    assert corners.env_kwargs == protocol.CONDITIONS["random-shifts"].env_kwargs  # observation bounds alike
    env = corners.make_env()
    drawn = []
    for seed in corners.seeds(30):
        params = env.reset(seed=seed, options=corners.options(seed))[1]["params"]
        assert params == corners.options(seed)["params"] and set(params) == set(ranges)
        assert all(params[path] in bounds for path, bounds in ranges.items())
        assert env.unwrapped.episode_params == DEFAULT_PARAMS.replace(params)
        drawn.append(tuple(params.values()))
    assert len(set(drawn)) == 30
    assert all({row[i] for row in drawn} == set(bounds) for i, bounds in enumerate(ranges.values()))  # both ends
    assert protocol.protocol_record(["corners"])["corners"]["corners"] == "all"
    result = protocol.evaluate("corners", lambda env: Hold(env), episodes=2)
    assert result["condition"] == "corners" and len(result["success"]) == 2


def test_evaluate_scores_a_plain_function_given_as_policy_as_its_factory_would():
    """policy=: a function obs -> action, no factory needed; the same episodes as the factory's."""
    def hold(obs):
        return np.zeros(3)

    given = protocol.evaluate("c11-starts", policy=hold, episodes=2)
    made = protocol.evaluate("c11-starts", lambda env: hold, episodes=2)
    assert given["condition"] == "c11-starts"
    for key in ("success", "collisions", "energy", "return"):
        np.testing.assert_array_equal(given[key], made[key])
    with pytest.raises(TypeError, match="one of policy_factory .* and policy .*, got both"):
        protocol.evaluate("c11", lambda env: hold, policy=hold, episodes=1)
    with pytest.raises(TypeError, match="got neither"):
        protocol.evaluate("c11", episodes=1)
