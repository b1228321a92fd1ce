"""Old home of the stable-baselines3 adapter, kept so that ``scara_gym.sb3.SB3VecEnv`` still
imports; it lives in `scara_gym.integrations.sb3`.
"""

from scara_gym.integrations.sb3 import SB3VecEnv

__all__ = ["SB3VecEnv"]
