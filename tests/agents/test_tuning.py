"""agents.experiments.tuning: the heuristic's distance is chosen once, on the tuning set, by its rule."""

from agents.experiments import tuning
from agents.policies import DecHeuristic, run_episode
from scara_gym.benchmark import protocol


def clears(distance, pairs):
    for condition, seed in pairs:
        env = condition.make_env("pd")
        result = run_episode(env, DecHeuristic(env, "continue", critical_distance=distance), seed=seed,
                             options=condition.options(seed))
        if result["collisions"] or not result["success"]:
            return False
    return True


def test_the_tuned_distance_is_the_smallest_that_clears_the_tuning_set_and_no_evaluation_seed():
    tuned = tuning.tune_heuristic("continue", episodes=5, tolerance=2e-3)
    pairs = tuning.tuning_episodes(5)
    assert tuned["episodes"] == len(pairs) == 6
    assert all(protocol.TUNING_SEED <= seed < protocol.EVALUATION_SEED for c, seed in pairs[1:])
    assert pairs[0][0].name == "c11"  # the one nominal episode
    assert clears(tuned["distance"], pairs)
    assert not clears(tuned["distance"] - 2e-3, pairs)  # the bisection's bracket: just below fails
    assert tuned["margin_distance"] == tuning.MARGIN * tuned["distance"]
