"""Scara-C11-v0: API conventions, the task-b equivalence, collisions, the card, bad input."""

import ast
import inspect
import itertools
import math
import pickle
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import scara_gym  # noqa: F401  (registers the environment)
from scara_gym.benchmark.tasks import sample_point_to_point
from scara_gym.envs import ParameterRanges, ScaraEnv
from scara_gym.envs.config import FIELDS, EnvConfig
from scara_gym.envs.variants import card_of
from scara_gym.model.simulator import SimulationError, Simulator, start_state

C11_TARGET = np.array([2.0, 2.0, 0.3])


def rollout(env, actions, seed=None, options=None):
    obs, _ = env.reset(seed=seed, options=options)
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out.append((obs, reward, terminated, truncated, info["reward_terms"]))
        if terminated or truncated:
            break
    return out


def same_rollouts(a, b):
    if len(a) != len(b):
        return False
    for x, y in zip(a, b):
        if isinstance(x, np.ndarray):
            if not np.array_equal(x, y):
                return False
        elif not (np.array_equal(x[0], y[0]) and x[1:] == y[1:]):
            return False
    return True


HEADLESS_HUMAN = "render_mode='human' without a display"


@pytest.mark.parametrize("env_id", scara_gym.LATEST_IDS)
def test_gymnasium_check_env_passes_with_default_arguments_headless(env_id, monkeypatch):
    """Gymnasium's own check, as a user runs it on a headless machine: with its default
    arguments it re-makes the env in every declared render mode, "human" included."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(gym.make(env_id).unwrapped)
    # the one thing said: the human-mode env's note that it draws off-screen
    assert [str(w.message) for w in caught if HEADLESS_HUMAN not in str(w.message)] == []


@pytest.mark.parametrize("control_mode", ["pd", "voltage"])
def test_gymnasium_check_env_passes_without_warnings(control_mode):
    env = gym.make("Scara-C11-v2", control_mode=control_mode, render_mode="rgb_array",
                   randomize_target=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)  # "human" headless: the test above
        env.unwrapped.render()
    assert [str(w.message) for w in caught] == []


def test_stable_baselines3_check_env_passes():
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    for control_mode in ("pd", "voltage"):
        env = ScaraEnv(control_mode=control_mode)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sb3_checker.check_env(env, warn=True)
        assert [str(w.message) for w in caught] == []


def test_make_without_import_and_registration():
    env = gym.make("scara_gym:Scara-C11-v0")
    assert env.spec.max_episode_steps == 300
    assert env.unwrapped.metadata["render_fps"] == pytest.approx(100)
    assert ScaraEnv(control_dt=0.02).metadata["render_fps"] == pytest.approx(50)


def test_pd_mode_holding_the_c11_target_reproduces_task_b():
    env = ScaraEnv(control_mode="pd", obstacle=False)
    env.reset(seed=0)
    action = env.setpoint_to_action(C11_TARGET)
    states, info, steps = [], {}, 0
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(action)
        steps += 1
        states.append((env.time, env.state))
    assert info["is_success"] and terminated
    assert abs(info["reach_time"] - 1.5703) < env.control_dt
    assert steps == math.ceil(info["reach_time"] / env.control_dt)
    times = [t for t, _ in states]
    reference = sample_point_to_point(times)
    for (t, x), ref in zip(states, reference):
        assert np.max(np.abs(x[:3] - ref[:3])) < 1e-4, t


def test_collision_between_control_steps_is_located_inside_the_step():
    # a slow controller: 0.25 s per step, full voltage on axis 1 sweeps the tip through the wall
    env = ScaraEnv(control_mode="voltage", collision="penalty", control_dt=0.25)
    env.reset(seed=0)
    x_obs = env.params.obstacle.x_position
    collided_in = None
    for step in range(4):
        tip_before = env.unwrapped._tip()
        _, _, _, _, info = env.step(np.array([1.0, 0.0, 0.0], dtype=np.float32))
        if info["collision"]:
            collided_in = (step, tip_before[0], env._tip()[0], info)
            break
    assert collided_in is not None
    step, x_before, x_after, info = collided_in
    assert x_before > x_obs > x_after  # both samples miss the wall: only located events see it
    assert info["cost"] == 1.0 and info["collisions"] == 1
    # the located instant is the one of a direct simulation of the same inputs
    sim = Simulator(env.params, control="voltage", critical="switch", widen=True, wall=True,
                    stop=("collision",), rtol=1e-10, atol=1e-12)
    sim.reset(start_state(env.params), command=[1.0, 0.0, 0.0])
    sim.advance(2.0)
    event_time = sim.events()[-1].time
    assert step * 0.25 < event_time < (step + 1) * 0.25
    assert env.time == pytest.approx((step + 1) * 0.25)  # penalty: the step runs to its end

    terminate = ScaraEnv(control_mode="voltage", collision="terminate", control_dt=0.25)
    terminate.reset(seed=0)
    for _ in range(4):
        _, reward, terminated, truncated, info = terminate.step(np.array([1.0, 0.0, 0.0]))
        if terminated:
            break
    assert terminated and not truncated and info["collision"]
    assert terminate.time == pytest.approx(event_time, abs=1e-6)  # the step ends at the wall
    assert info["reward_terms"]["collision"] == -terminate.reward_weights.collision
    with pytest.raises(RuntimeError, match="reset"):
        terminate.step(np.zeros(3))


def test_plain_pd_hits_the_wall():
    env = gym.make("Scara-C11-v0")
    env.reset(seed=0)
    action = env.unwrapped.setpoint_to_action(C11_TARGET)
    while True:
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert terminated and info["collision"] and not info["is_success"]
    assert info["time"] == pytest.approx(0.36, abs=0.01)


def test_voltage_mode_spans_the_widened_limit_while_critical():
    env = ScaraEnv(control_mode="voltage", collision="penalty")
    env.reset(seed=0)
    action = np.array([1.0, 0.0, -1.0])
    seen = set()
    for _ in range(100):
        _, _, terminated, _, info = env.step(action)
        limits = np.array(env.params.obstacle.wide_voltage_limits if info["critical"]
                          else env.params.voltage_limits)
        assert np.allclose(info["voltage"], action * limits)
        seen.add(info["critical"])
        if terminated:
            break
    assert seen == {False, True}


def test_same_seed_same_actions_identical_rollouts():
    actions = np.random.default_rng(3).uniform(-1, 1, size=(60, 3))
    for control_mode in ("pd", "voltage"):
        a = rollout(ScaraEnv(control_mode=control_mode, randomize_target=True), actions, seed=7)
        b = rollout(ScaraEnv(control_mode=control_mode, randomize_target=True), actions, seed=7)
        c = rollout(ScaraEnv(control_mode=control_mode, randomize_target=True), actions, seed=8)
        assert same_rollouts(a, b)
        assert not same_rollouts(a, c)


def test_reset_without_seed_continues_the_rng_stream():
    env_a, env_b = ScaraEnv(randomize_target=True), ScaraEnv(randomize_target=True)
    first = env_a.reset(seed=11)[1]["target"]
    second = env_a.reset()[1]["target"]
    env_b.reset(seed=11)
    assert not np.array_equal(first, second)
    assert np.array_equal(env_b.reset()[1]["target"], second)


def test_randomized_targets_lie_in_the_documented_region():
    env = ScaraEnv(randomize_target=True)
    obs_params = env.params.obstacle
    for seed in range(50):
        target = env.reset(seed=seed)[1]["target"]
        assert np.all(target >= [1.5, 1.5, 0.2]) and np.all(target <= [2.5, 2.5, 0.35])
        x_tip = 0.4 * math.cos(target[0]) + 0.3 * math.cos(target[0] + target[1])
        assert x_tip < obs_params.x_position - obs_params.critical_distance - 0.02
        assert target[2] >= obs_params.height + 0.02


def test_pickling_round_trips_mid_episode():
    env = ScaraEnv(control_mode="voltage", randomize_target=True)
    env.reset(seed=5)
    for _ in range(10):
        env.step(np.array([0.5, -0.2, 0.8]))
    clone = pickle.loads(pickle.dumps(env))
    actions = np.random.default_rng(0).uniform(-1, 1, size=(20, 3))
    for a in actions:
        left, right = env.step(a), clone.step(a)
        assert np.array_equal(left[0], right[0]) and left[1] == right[1]


@pytest.mark.parametrize("control_mode", ["pd", "voltage"])
def test_a_restored_snapshot_goes_on_as_the_episode_it_was_taken_from(control_mode):
    """The vector env's snapshot / restore: a robot put in another episode's state at step k takes
    the same steps from there, bit for bit, up to the same truncation step of the vector env
    (whose time limit reads the task's step count; a single env's TimeLimit wrapper counts its own)."""
    rng = np.random.default_rng(4)
    actions = rng.uniform(-1, 1, size=(300, 1, 3))
    source, copy = (gym.make_vec("Scara-C11-v1", num_envs=1, vectorization_mode="vector_entry_point",
                                 control_mode=control_mode) for _ in range(2))
    source.reset(seed=0)
    for a in actions[:37]:
        source.step(a)
    snapshot = source.unwrapped.snapshot(0)
    copy.reset(seed=1)
    copy.unwrapped.restore(0, snapshot)
    assert np.array_equal(copy.unwrapped.noise_free_observation(0), source.unwrapped.noise_free_observation(0))
    for k, a in enumerate(actions[37:], start=38):  # noqa: B007  (the step it ends on is kept)
        left, right = source.step(a), copy.step(a)
        assert all(np.array_equal(x, y) for x, y in zip(left[:4], right[:4]))
        assert left[4].keys() == right[4].keys()
        for key in left[4]:
            if not key.startswith("final"):
                np.testing.assert_array_equal(left[4][key], right[4][key])  # NaN where both NaN
        if left[2][0] or left[3][0]:
            break
    assert k == 300 and left[3][0]  # the time limit counted from the source's start
    single = gym.make("Scara-C11-v1", control_mode=control_mode).unwrapped
    single.reset(seed=0, options={"target": [1.0, 1.0, 0.2]})
    with pytest.raises(ValueError, match="another target or other parameters"):
        single.restore(snapshot)
    delayed = gym.make("Scara-C11-v1", control_mode=control_mode, action_delay=1)
    delayed.reset(seed=0)
    with pytest.raises(ValueError, match="action_delay"):
        delayed.unwrapped.restore(snapshot)


@pytest.mark.parametrize("control_mode", ["pd", "voltage"])
def test_a_snapshot_carries_the_actuator_line_and_restores_the_continuation(control_mode):
    """With a delay and a rate limit the snapshot holds the line's pending and applied actions: a
    copy restored from it goes on exactly as the source does."""
    kwargs = dict(control_mode=control_mode, action_delay=2, action_rate_limit=30.0)
    source, copy = gym.make("Scara-C11-v1", **kwargs), gym.make("Scara-C11-v1", **kwargs)
    rng = np.random.default_rng(5)
    actions = rng.uniform(-1.0, 1.0, (60, 3))
    source.reset(seed=0)
    for action in actions[:20]:
        source.step(action)
    snapshot = source.unwrapped.snapshot()
    assert snapshot["pending"].shape == (2, 3) and snapshot["applied"].shape == (3,)
    copy.reset(seed=0)
    copy.unwrapped.restore(snapshot)
    for action in actions[20:]:
        left, right = source.step(action), copy.step(action)
        np.testing.assert_array_equal(left[0], right[0])
        np.testing.assert_array_equal(left[4]["applied_action"], right[4]["applied_action"])
        if left[2]:
            break
    other = gym.make("Scara-C11-v1", control_mode=control_mode, action_delay=1)
    other.reset(seed=0)
    with pytest.raises(ValueError, match="action_delay 1\\) needs a snapshot with its state"):
        other.unwrapped.restore(snapshot)


def test_reward_terms_sum_to_the_reward_and_observations_stay_in_the_space():
    env = ScaraEnv(control_mode="voltage", collision="penalty", randomize_target=True)
    obs, _ = env.reset(seed=2)
    rng = np.random.default_rng(2)
    for _ in range(150):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 3))
        assert obs.dtype == np.float32 and env.observation_space.contains(obs)
        assert reward == pytest.approx(sum(info["reward_terms"].values()), abs=1e-12)
        assert set(info["reward_terms"]) == {"progress", "time", "energy", "collision", "success"}
        if terminated:
            break


def test_success_reward_and_terms_on_the_successful_step():
    env = ScaraEnv(obstacle=False)
    env.reset(seed=0)
    action = env.setpoint_to_action(C11_TARGET)
    total = 0.0
    while True:
        _, reward, terminated, _, info = env.step(action)
        total += reward
        if terminated:
            break
    assert info["reward_terms"]["success"] == env.reward_weights.success
    # progress sums to the weight times the start distance minus the final distance
    assert info["energy"] > 0


def test_every_mode_and_option_combination_runs_an_episode_to_its_end():
    rng = np.random.default_rng(0)
    for control_mode, obstacle, collision, randomize in itertools.product(
            ("pd", "voltage"), (True, False), ("terminate", "penalty"), (False, True)):
        env = gym.make("Scara-C11-v0", control_mode=control_mode, obstacle=obstacle,
                       collision=collision, randomize_target=randomize)
        env.reset(seed=int(rng.integers(1000)))
        for _ in range(301):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                break
        assert terminated or truncated, (control_mode, obstacle, collision, randomize)


def test_reset_options_override_target_and_start():
    env = ScaraEnv()
    obs, info = env.reset(seed=0, options={"target": [1.8, 2.1, 0.25], "start": [0.1, 0.0, 0.05]})
    assert np.allclose(info["target"], [1.8, 2.1, 0.25])
    assert np.allclose(obs[:3], [0.1, 0.0, 0.05])
    assert np.allclose(obs[9:12], np.array([1.8, 2.1, 0.25]) - [0.1, 0.0, 0.05], atol=1e-6)
    _, info = env.reset()
    assert np.allclose(info["target"], C11_TARGET)


@pytest.mark.parametrize("action, words", [
    (np.zeros(2), "shape (3,)"),
    (np.zeros((3, 1)), "shape (3,)"),
    (np.array([0.0, np.nan, 0.0]), "finite"),
    (np.array([np.inf, 0.0, 0.0]), "finite"),
    ("fast", "action must be"),
])
def test_bad_actions_raise_clear_errors(action, words):
    env = ScaraEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError) as info:
        env.step(action)
    assert words in str(info.value)
    env.step(np.zeros(3))  # the state is not lost


@pytest.mark.parametrize("wild", [
    np.array([3.0, -2.0, 0.5]),                     # float64, the compiled fast path
    np.array([3.0, -2.0, 0.5], dtype=np.float32),   # float32, the action space's dtype
    [3.0, -2.0, 0.5],                               # a list: converted first
    np.array([[3.0, 9.0], [-2.0, 9.0], [0.5, 9.0]])[:, 0],  # not contiguous
])
def test_out_of_range_actions_are_clipped_and_counted(wild):
    env, twin = ScaraEnv(control_mode="voltage"), ScaraEnv(control_mode="voltage")
    env.reset(seed=0)
    twin.reset(seed=0)
    obs, _, _, _, info = env.step(wild)
    obs_clipped, _, _, _, info_clipped = twin.step(np.array([1.0, -1.0, 0.5]))
    assert info["clipped_actions"] == 2 and info_clipped["clipped_actions"] == 0
    assert np.array_equal(obs, obs_clipped)


@pytest.mark.parametrize("kwargs, error, words", [
    (dict(control_mode="torque"), ValueError, "control_mode must be one of"),
    (dict(collision="bounce"), ValueError, "collision must be one of"),
    (dict(control_dt=0.0), ValueError, "control_dt must be"),
    (dict(target=[2.0, 2.0, np.nan]), ValueError, "target must be 3 finite"),
    (dict(target=[5.0, 2.0, 0.3]), ValueError, "q1, q2 in [-pi, pi] rad"),
    (dict(params={"arm.load_mass": -1.0}), ValueError, "ArmParams.load_mass"),
    (dict(params={"arm.weight": 1.0}), KeyError, "arm.weight"),
    (dict(reward_weights={"speed": 1.0}), ValueError, "unknown terms"),
    (dict(reward_weights={"time": -1.0}), ValueError, "reward_weights.time"),
    (dict(render_mode="ascii"), ValueError, "render_mode must be one of"),
])
def test_bad_constructor_arguments(kwargs, error, words):
    with pytest.raises(error, match=re.escape(words)):
        ScaraEnv(**kwargs)


@pytest.mark.parametrize("options, words", [
    ({"goal": [1, 2, 3]}, "unknown reset options"),
    ({"target": [np.nan, 2.0, 0.3]}, "options['target'] must be 3 finite"),
    ({"start": [0.0, 0.0]}, "options['start'] must be 3 finite"),
    ({"start": [2.0, 2.0, 0.3]}, "already within acc"),
])
def test_bad_reset_options(options, words):
    env = ScaraEnv()
    with pytest.raises(ValueError, match=re.escape(words)):
        env.reset(seed=0, options=options)


def test_rgb_array_renders_headless_and_human_draws_off_screen_without_a_display(monkeypatch):
    env = ScaraEnv(render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(3))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 0  # something is drawn
    env.close()
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.warns(UserWarning, match=re.escape(HEADLESS_HUMAN)):
        human = ScaraEnv(render_mode="human")
    assert human.render_mode == "human"
    human.reset(seed=0)
    human.step(np.zeros(3))
    assert human.render() is None  # Gymnasium's convention for "human"; the figure is drawn off-screen
    assert human._renderer.figure.canvas.__class__.__name__ == "FigureCanvasAgg"
    human.close()


# -- the card ---------------------------------------------------------------------------------
def _table(doc: str, header: str) -> list[list[str]]:
    start = doc.index(header)
    rows = []
    for line in doc[start:].splitlines()[1:]:
        line = line.strip()
        if not line.startswith("|"):
            if rows:
                break
            continue
        cells = [c.strip() for c in line.strip("|").split("|")]
        if set("".join(cells)) <= {"-"}:
            continue
        rows.append(cells)
    return rows


# the goal env's card (a Dict observation) has its own test in test_goal.py; a variant's card is
# ScaraEnv's with its latest version's registered arguments
@pytest.mark.parametrize("env_id", [None, "Scara-C11-RandomPhysics-v1", "Scara-C11-RandomWall-v1"])
def test_the_card_matches_the_spaces_and_arguments(env_id):
    doc = inspect.getdoc(ScaraEnv) if env_id is None else card_of(env_id)
    config = EnvConfig() if env_id is None else EnvConfig(**scara_gym.ENV_KWARGS[env_id])
    env = ScaraEnv(config)
    rows = _table(doc, "| index | name | unit | low | high |")
    assert [int(r[0]) for r in rows] == list(range(env.observation_space.shape[0]))
    assert [r[1] for r in rows] == list(env.observation_names)
    assert np.allclose([float(r[3]) for r in rows], env.observation_space.low, atol=1e-4)
    assert np.allclose([float(r[4]) for r in rows], env.observation_space.high, atol=1e-4)
    assert f"Box(low, high, ({env.observation_space.shape[0]},), float32)" in doc

    actions = _table(doc, "| control_mode | index | meaning | unit |")
    assert sorted({r[0] for r in actions}) == ["pd", "voltage"]
    assert all(len([r for r in actions if r[0] == m]) == env.action_space.shape[0] for m in ("pd", "voltage"))
    for r in actions:
        if r[0] == "pd":  # the documented set-point mapping is the one the env applies
            a = np.zeros(3)
            a[int(r[1])] = 1.0
            setpoint = env.action_to_setpoint(a)[int(r[1])]
            expected = {"0": math.pi, "1": math.pi, "2": 0.4}[r[1]]
            assert setpoint == pytest.approx(expected)

    arguments = doc[doc.index("## Arguments"):doc.index("## Version history")]
    documented = dict(re.findall(r"^- (\w+) \(([^)]*)\)", arguments, flags=re.M))
    # every field of the configuration, with the card's defaults, and the env's own render_mode
    assert list(documented) == [*FIELDS, "render_mode"]
    assert list(inspect.signature(ScaraEnv.__init__).parameters) == ["self", "config", "render_mode", "overrides"]
    for name in FIELDS:
        assert documented[name] == repr(getattr(config, name)).replace("'", '"'), name
    assert documented["render_mode"] == "None"
    assert "max_episode_steps=300" in doc and gym.spec("Scara-C11-v0").max_episode_steps == 300


def test_an_integration_that_cannot_go_on_names_its_cause():
    env = ScaraEnv(control_mode="voltage")
    env.reset(seed=0)
    env._task.step_config["max_steps"] = 3  # a step budget far below what one control step needs
    with pytest.raises(SimulationError, match=r"max_steps = 3 step attempts used up"):
        env.step(np.ones(3))


@pytest.mark.parametrize("env_id", scara_gym.ENV_IDS)
def test_each_registered_id_fixes_its_integration_arguments(env_id):
    fixed = dict(scara_gym.ENV_KWARGS[env_id])
    randomized = fixed.pop("randomize_params", False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # v0 is out of date, on purpose
        env = gym.make(env_id).unwrapped
        vector_task = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")._task
    for task_ in (env._task, vector_task):
        assert {name: getattr(task_, name) for name in fixed} == fixed
        expected = ParameterRanges.from_argument(randomized, task_.params)
        assert task_.randomization == expected
    assert gym.spec(env_id).max_episode_steps == 300
    version = env_id.rsplit("-", 1)[1]
    card = card_of(env_id)
    history = card[card.index("## Version history"):]
    line = re.search(rf"^- {version}: (.*?)(?=^- |\Z)", history, flags=re.M | re.S).group(1)
    stated = dict(re.findall(r"``(\w+)=([^`]+)``", line))
    # the card's line says what the id fixes
    assert {name: ast.literal_eval(stated[name]) for name in scara_gym.ENV_KWARGS[env_id]} == \
        scara_gym.ENV_KWARGS[env_id]


@pytest.mark.parametrize("env_id", ["Scara-C11-v1", "Scara-C11-v2"])
def test_exact_ids_are_deterministic_for_a_seed_and_pass_check_env(env_id):
    runs = []
    for _ in range(2):
        env = gym.make(env_id, control_mode="voltage", randomize_target=True)
        obs, _ = env.reset(seed=11)
        rng = np.random.default_rng(11)
        trace = [obs]
        for _ in range(150):
            obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
            trace.append(np.append(obs, reward))
            if terminated or truncated:
                break
        runs.append(np.concatenate(trace))
    assert np.array_equal(runs[0], runs[1])
    env = gym.make(gym.spec(env_id)).unwrapped  # v1 on purpose: from its spec, not called out of date
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    assert [str(w.message) for w in caught] == []


def test_randomize_start_draws_the_start_per_episode_inside_its_region():
    from scara_gym.envs.task import START_REGION

    env = gym.make("Scara-C11-v2", randomize_start=True, randomize_target=True)
    starts = np.array([env.reset(seed=s)[1]["start"] for s in range(50)])
    low, high = START_REGION
    assert np.all(starts >= low) and np.all(starts <= high) and len({tuple(s) for s in starts}) == 50
    obs, info = env.reset(seed=7)
    assert np.allclose(obs[:3], info["start"], atol=1e-7)  # the robot starts there, at rest
    np.testing.assert_array_equal(env.reset(seed=7)[1]["start"], info["start"])  # seeded
    np.testing.assert_array_equal(env.reset(seed=7, options={"start": [0.1, 0.0, 0.0]})[1]["start"], [0.1, 0.0, 0.0])
    own = gym.make("Scara-C11-v2", randomize_start=([0.0, 0.0, 0.0], [0.0, 0.0, 0.1]))
    assert np.all(own.reset(seed=1)[1]["start"][:2] == 0.0)
    fixed = gym.make("Scara-C11-v2")
    assert np.all(fixed.reset(seed=3)[1]["start"] == 0.0)
    for bad in ("yes", ([0.1, 0, 0], [0.0, 0, 0]), ([0, 0, 0], [2.0, 0, 0]), ([0, 0], [0, 0])):
        with pytest.raises(ValueError, match="randomize_start must be False, True or \\(low, high\\)"):
            gym.make("Scara-C11-v2", randomize_start=bad)


def test_the_dec_error_names_a_policy_that_exists():
    import re

    import agents.policies

    with pytest.raises(ValueError, match="obstacle.dec") as error:
        gym.make("Scara-C11-v2", params={"obstacle.dec": 0.1})
    named = re.findall(r"agents\.policies\.(\w+)", str(error.value))
    assert named and all(hasattr(agents.policies, name) for name in named)
