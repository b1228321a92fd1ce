"""Adapters to other libraries: :mod:`scara_gym.integrations.sb3` (stable-baselines3)."""
