"""Adapters to other libraries: `scara_gym.integrations.sb3` (stable-baselines3)."""
