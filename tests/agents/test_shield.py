"""scara_gym.wrappers.shield: the model-predictive shield keeps any policy off the wall, and leaves a policy
that stays safe alone."""

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401
from agents.experiments.evaluation import make_policy
from agents.policies import DecHeuristic, PDPolicy, run_episode
from scara_gym.wrappers import Shield


class NoisyPD(PDPolicy):
    """PD towards the target (which drives through the wall) with uniform noise on its
    actions, from its own generator."""

    def __init__(self, env, seed: int, noise: float = 0.5) -> None:
        super().__init__(env)
        self.rng, self.noise = np.random.default_rng(seed), noise

    def __call__(self, obs):
        return np.clip(super().__call__(obs) + self.rng.uniform(-self.noise, self.noise, 3), -1.0, 1.0)


@pytest.mark.parametrize("mode", ["pd", "voltage"])
def test_the_shield_takes_pd_past_the_wall_it_hits_alone(mode):
    env = gym.make("Scara-C11-v1", control_mode=mode)
    alone = run_episode(env, PDPolicy(env), seed=0)
    assert alone["collisions"] > 0 and not alone["success"]
    shield = Shield(env, PDPolicy(env))
    shielded = run_episode(env, shield, seed=0)
    assert shielded["collisions"] == 0 and shielded["success"]
    assert 0 < shield.interventions < shielded["steps"]


def test_a_policy_that_stays_clear_is_left_as_it_is():
    env = gym.make("Scara-C11-v1")
    heuristic = DecHeuristic(env, "continue", critical_distance=0.06)
    alone = run_episode(env, heuristic, seed=0)
    shield = Shield(env, DecHeuristic(env, "continue", critical_distance=0.06))
    shielded = run_episode(env, shield, seed=0)
    assert shield.interventions == 0
    for key in ("success", "collisions", "reach_time", "energy", "steps"):
        assert shielded[key] == alone[key], key


@pytest.mark.parametrize("mode", ["pd", "voltage"])
def test_noisy_actions_behind_the_shield_never_touch_the_wall(mode):
    """With the episode's own parameters the model is exact, so the backup is safe wherever the
    shield let the robot go: not one collision, though the policy alone collides."""
    env = gym.make("Scara-C11-v1", control_mode=mode, randomize_target=True)
    alone = [run_episode(env, NoisyPD(env, seed), seed=seed)["collisions"] for seed in range(6)]
    assert sum(alone) > 0
    interventions = 0
    for seed in range(6):
        shield = Shield(env, NoisyPD(env, seed))
        assert run_episode(env, shield, seed=seed)["collisions"] == 0
        interventions += shield.interventions
    assert interventions > 0


def test_the_nominal_model_is_the_default_and_params_give_another():
    shifted = scara_gym.DEFAULT_PARAMS.replace({"obstacle.x_position": 0.37})
    env = gym.make("Scara-C11-v1", params=shifted)
    assert Shield(env, PDPolicy(env)).model.params == scara_gym.DEFAULT_PARAMS
    assert Shield(env, PDPolicy(env), params=None).model.params == shifted


def test_bad_arguments_are_refused_by_name():
    env = gym.make("Scara-C11-v1")
    with pytest.raises(ValueError, match="horizon must be an integer in \\[1, 1000\\]"):
        Shield(env, PDPolicy(env), horizon=0)
    with pytest.raises(ValueError, match="rest_rate must be a finite number > 0"):
        Shield(env, PDPolicy(env), rest_rate=-1.0)
    with pytest.raises(ValueError, match="climb_margin must be a finite number > 0"):
        Shield(env, PDPolicy(env), climb_margin=float("nan"))
    delayed = gym.make("Scara-C11-v1", action_delay=1)
    with pytest.raises(ValueError, match="action_delay / action_rate_limit"):
        Shield(delayed, PDPolicy(delayed))


def test_shield_is_a_policy_spec_of_evaluate():
    env = gym.make("Scara-C11-v1")
    policy = make_policy("shield:dec-continue:0.06", env)
    assert isinstance(policy, Shield) and isinstance(policy.policy, DecHeuristic)
    assert policy.name == "dec-continue (d=0.06 m) + shield"
    with pytest.raises(ValueError, match="shield:SPEC"):
        make_policy("shield:", env)
