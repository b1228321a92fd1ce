"""Agents for the scara_gym environments, in layers that import downwards only:

- `agents.policies`: things that act (PD, the seed's ``dec`` heuristic, the optimal reference);
- `agents.algorithms`: things that train (the single-file torch PPO, stable-baselines3);
- `agents.experiments`: things that orchestrate and report (the run registry, training
  campaigns, one evaluation engine, the comparison, sweeps, checkpoint selection, benchmarks);
- `agents.cli`: the ``scara-agents`` console script.
"""
