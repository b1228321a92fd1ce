"""Success at several precisions (scara_gym.benchmark.episodes): the looser bands' times from the
start and the control steps' ends, never later than the located C11 success, inside the one
episode loop, with the C11 figures as they were."""

import math

import numpy as np
import pytest

import scara_gym  # noqa: F401
from scara_gym.benchmark import protocol
from scara_gym.benchmark.episodes import BAND_NAMES, BANDS, band_keys, band_times, run_episodes
from scara_gym.envs import OBSERVATION_LAYOUT
from scara_gym.wrappers import Shield

TARGET_ERROR = OBSERVATION_LAYOUT["target_error"]


class CommandTheTarget:
    """PD's set-point, the target (it alone collides with the wall)."""

    def __init__(self, env):
        self.env = env.unwrapped

    def reset(self):
        pass

    def __call__(self, obs):
        return self.env.setpoint_action(obs, obs[:3] + obs[TARGET_ERROR])


def shielded_pd(env):
    """The target commanded behind the shield: it passes the wall and arrives."""
    return Shield(env, CommandTheTarget(env))


def test_the_bands_are_the_c11_band_and_two_looser_ones():
    assert BAND_NAMES == ("1e-3", "1e-2", "5e-2") and BANDS == {"1e-2": 1e-2, "5e-2": 5e-2}
    assert band_keys("1e-3") == ("success", "reach_time")  # the environment's own success
    assert band_keys("1e-2") == ("success_1e-2", "reach_time_1e-2")


def test_band_times_on_a_constructed_trajectory():
    times = np.arange(8) * 0.01  # the start and seven step ends
    errors = [0.3, 0.06, 0.05, 0.049, 0.0101, 0.01, 0.0099, 0.002]
    # strictly inside: 0.05 is not inside 5e-2, nor 0.01 inside 1e-2
    assert band_times(errors, times) == {"1e-2": times[6], "5e-2": times[3]}
    # the located C11 instant bounds every band (the state passed through them before it)
    assert band_times(errors, times, located=0.055) == {"1e-2": 0.055, "5e-2": times[3]}
    assert band_times(errors, times, located=0.025) == {"1e-2": 0.025, "5e-2": 0.025}
    never = band_times([0.3, 0.2, 0.06], [0.0, 0.01, 0.02])
    assert all(math.isnan(t) for t in never.values())
    assert band_times([0.3, 0.2, 0.06], [0.0, 0.01, 0.02], located=0.015) == {"1e-2": 0.015, "5e-2": 0.015}
    inside = band_times([0.04, 0.2, 0.005], [0.0, 0.01, 0.02])  # a start already inside the loose band
    assert inside == {"1e-2": 0.02, "5e-2": 0.0}


def _observed_band_times(env, policy, seed, options):
    """The bands' times as a user would measure them from the observations (no noise: the
    observed target error is the state's, in float32), and the episode's C11 figures."""
    obs, _ = env.reset(seed=seed, options=options)
    policy.reset()
    found = {name: (0.0 if np.max(np.abs(obs[TARGET_ERROR])) < band else np.nan) for name, band in BANDS.items()}
    total = 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        for name, band in BANDS.items():
            if np.isnan(found[name]) and np.max(np.abs(obs[TARGET_ERROR])) < band:
                found[name] = info["time"]
        if terminated or truncated:
            break
    if info["is_success"]:
        found = {name: min(t, info["reach_time"]) if not np.isnan(t) else info["reach_time"]
                 for name, t in found.items()}
    c11 = {"success": info["is_success"], "reach_time": info.get("reach_time", np.nan), "energy": info["energy"],
           "return": total, "collision_counts": info["collisions"]}
    return found, c11


@pytest.mark.parametrize("name", ["c11-starts", "random-targets"])
def test_the_band_times_are_the_first_step_ends_inside_and_the_c11_figures_are_unchanged(name):
    """run_episodes' band times are those measured from the observations; the C11 band's figures
    (success, reach_time, energy, return, collisions) are the episode's own, bit for bit."""
    condition = protocol.CONDITIONS[name]
    seeds = condition.seeds(3)
    options = [condition.options(s) for s in seeds]
    env = condition.make_env()
    result = run_episodes(env, shielded_pd(env), seeds, options)
    check_env = condition.make_env()
    policy = shielded_pd(check_env)
    for i, (seed, option) in enumerate(zip(seeds, options)):
        found, c11 = _observed_band_times(check_env, policy, seed, option)
        for band, t in found.items():
            assert result[f"reach_time_{band}"][i] == pytest.approx(t, abs=1e-12, nan_ok=True), (seed, band)
            assert result[f"success_{band}"][i] == (not np.isnan(t))
        for key, value in c11.items():
            assert np.array_equal(result[key][i], value, equal_nan=True), (seed, key)
    assert result["success"].all()  # the shielded PD arrives: the comparison below is not vacuous


@pytest.mark.parametrize("name", ["c11-starts", "random-targets", "sensor-noise", "rate-limit-20"])
def test_a_looser_band_is_never_reported_later_than_a_tighter_one(name):
    """time to 5e-2 <= time to 1e-2 <= time to 1e-3 where reached; success at a band implies success
    at every looser one (also where the observations are noisy: the bands read the true state)."""
    result = protocol.evaluate(name, shielded_pd, episodes=3)
    times = [result[band_keys(band)[1]] for band in BAND_NAMES]
    reached = [result[band_keys(band)[0]] for band in BAND_NAMES]
    for tight, loose in zip(reached, reached[1:]):
        assert np.all(loose >= tight)
    for tight, loose in zip(times, times[1:]):
        both = ~np.isnan(tight) & ~np.isnan(loose)
        assert np.all(loose[both] <= tight[both])
    assert reached[0].any() and np.all(times[-1][reached[0]] < times[0][reached[0]])  # looser: sooner, here


def test_an_episode_that_never_arrives_reaches_no_band_and_the_shortcut_keeps_the_bands():
    c11 = protocol.CONDITIONS["c11"]
    env = c11.make_env()
    still = run_episodes(env, lambda obs: np.zeros(3), [0, 1])  # a zero action in "pd" mode holds the start
    for band in BANDS:
        assert not still[f"success_{band}"].any() and np.isnan(still[f"reach_time_{band}"]).all()
    full, short = (run_episodes(env, shielded_pd(env), list(range(4)), identical=same) for same in (False, True))
    for key in [k for band in BAND_NAMES for k in band_keys(band)]:
        assert np.array_equal(full[key], short[key], equal_nan=True), key
