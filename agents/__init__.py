"""Agents for the scara_gym environments, in layers that import downwards only:

- :mod:`agents.policies`: things that act (PD, the seed's ``dec`` heuristic, the optimal reference);
- :mod:`agents.algorithms`: things that train (the single-file torch PPO, stable-baselines3);
- :mod:`agents.experiments`: things that orchestrate and report (the run registry, training
  campaigns, one evaluation engine, the comparison, sweeps, checkpoint selection, benchmarks);
- :mod:`agents.cli`: the ``scara-agents`` console script.
"""
