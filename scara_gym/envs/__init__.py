from scara_gym.envs.scara_env import RewardWeights, ScaraEnv

__all__ = ["RewardWeights", "ScaraEnv"]
