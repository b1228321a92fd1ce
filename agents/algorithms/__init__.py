"""Things that train, each with the loader of what it saved as a policy.

- `agents.algorithms.torch_ppo`: PPO in one file (torch; CPU or the CUDA env), with its
  research add-ons as hooks in `agents.algorithms.torch_ppo_hooks`;
- `agents.algorithms.sb3`: stable-baselines3's PPO, SAC and TD3 (resumable training,
  the YAML hyperparameters, the HER buffer, the saved-model policies);
- `agents.algorithms.loaders`: the one table from a policy spec's kind to its loader
  (``pd``, ``shield:SPEC``, ``torchppo:DIR``, a bare run folder, ...): ``load_policy(spec, env)``.
"""
