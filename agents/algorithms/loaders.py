"""The one way from a policy spec to the policy that acts: one table from a spec's kind to its loader.

A spec is ``KIND`` or ``KIND:ARG``:

- ``pd``; ``dec-continue[:d]`` and ``dec-restart[:d]`` (the seed's heuristic with trigger distance
  d [m]); ``optimal`` (the minimum-time reference, "voltage" mode); ``mpc`` (the nonlinear MPC
  with its defaults, "voltage" or "pd" mode); ``mpc-rti`` (the same problem by a real-time
  iteration on HPIPM, agents.policies.mpc_rti, "voltage" or "pd" mode);
- ``run:DIR``, or the bare folder ``DIR``: a finished run of any trainer, loaded by the trainer its
  folder records (agents.files.recorded_run: run.json, else its config.json);
- ``sb3:DIR`` (any SB3 run: PPO, SAC, TD3), ``torchppo:DIR`` (a run of the single-file PPO),
  ``bc:DIR`` (a behaviour-cloning or DAgger run: the same MLP), ``ppo:NAME`` (a shipped model, e.g.
  ``ppo_pd``) or ``ppo:DIR``: the same runs with their trainer named;
- ``zoo:DIR``: a model RL Zoo trained (``python -m rl_zoo3.train ... -f LOGS``: its folder
  ``LOGS/ALGO/ENV_ID_N``, agents.algorithms.sb3.zoo);
- ``shield:SPEC``: the policy of SPEC behind scara_gym.wrappers.Shield (e.g. ``shield:pd``).

A known kind comes first: a folder named like one (``pd``) is given as ``./pd`` or ``run:pd``.
Every loader of a run checks its files as it always has (SB3's pickle only from a trusted folder,
agents.files.require_trusted; the weights against their digests, agents.files.verify_digests):
reading which trainer a folder records reads JSON only.

The table lives here, in the algorithms' layer, not in agents.policies: the learned policies'
loaders are the algorithms' (the torch ones import torch), and agents.policies sits below them
(tests/test_layers.py: the layers import downwards only).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from agents.algorithms.sb3.policy import PPOPolicy, SB3Policy, resolve_model
from agents.algorithms.sb3.zoo import ZooPolicy
from agents.files import recorded_run
from agents.policies import DecHeuristic, PDPolicy
from agents.policies.mpc import MPCPolicy
from agents.policies.mpc_rti import RTIMPCPolicy
from agents.policies.optimal import OptimalPolicy
from scara_gym.model.checks import UserError
from scara_gym.wrappers import Shield

POLICY_SPECS = ("pd, dec-continue[:d], dec-restart[:d], optimal, mpc, mpc-rti, RUN_DIR, run:RUN_DIR, "
                "ppo:NAME_OR_DIR, sb3:RUN_DIR, torchppo:RUN_DIR, bc:RUN_DIR, zoo:RL_ZOO_DIR, shield:SPEC")
"""the specs load_policy reads, as the command line's help and errors name them"""


def _heuristic(variant: str) -> Callable:
    def load(env, arg: str):
        try:
            distance = float(arg) if arg else 0.06
        except ValueError:
            raise UserError(f"dec-{variant}:d takes a trigger distance d in metres, got {arg!r}") from None
        return DecHeuristic(env, variant=variant, critical_distance=distance)

    return load


def _folder(kind: str, load: Callable) -> Callable:
    """A loader of a run folder (ARG): refused without one."""

    def loader(env, arg: str):
        if not arg:
            raise UserError(f"{kind} policies are given as {kind}:" + ("NAME (shipped) or ppo:MODEL_DIR"
                                                                       if kind == "ppo" else "RUN_DIR"))
        return load(env, arg)

    return loader


def _torch_ppo(env, run_dir: str):
    from agents.algorithms.torch_ppo import TorchPPOPolicy

    return TorchPPOPolicy(env, run_dir)


def _bc(env, run_dir: str):
    from agents.algorithms.bc import BCPolicy

    return BCPolicy(env, run_dir)


def _mpc(env, arg: str):
    if arg:
        raise UserError("the MPC is given as mpc (its defaults; agents.policies.mpc.MPCConfig sets the rest)")
    return MPCPolicy(env)


def _mpc_rti(env, arg: str):
    if arg:
        raise UserError("the real-time MPC is given as mpc-rti (its defaults; agents.policies.mpc_rti.RTIConfig "
                        "sets the rest)")
    return RTIMPCPolicy(env)


def _shield(env, arg: str):
    if not arg:
        raise UserError("shielded policies are given as shield:SPEC, e.g. shield:pd or shield:torchppo:RUN_DIR")
    return Shield(env, load_policy(arg, env))


TRAINERS = {"sb3": "sb3", "torch-ppo": "torchppo", "bc": "bc", "dagger": "bc"}
"""a run folder's recorded trainer (agents.files.recorded_run) -> the spec kind that loads its policy"""


def trainer_kind(run_dir: str | Path) -> str:
    """The spec kind that loads the run in ``run_dir``: the one of the trainer its folder records."""
    if not Path(run_dir).is_dir():
        raise FileNotFoundError(f"no run folder {str(run_dir)!r}")
    trainer = recorded_run(run_dir).get("trainer")
    if trainer not in TRAINERS:
        raise FileNotFoundError(f"{run_dir}: no run.json or config.json that names its trainer (one of "
                                f"{sorted(TRAINERS)}): not a run folder; give sb3:DIR, torchppo:DIR or bc:DIR")
    return TRAINERS[trainer]


def _run(env, run_dir: str):
    return LOADERS[trainer_kind(run_dir)](env, run_dir)


LOADERS: dict[str, Callable] = {
    "pd": lambda env, arg: PDPolicy(env),
    "dec-continue": _heuristic("continue"),
    "dec-restart": _heuristic("restart"),
    "optimal": lambda env, arg: OptimalPolicy(env),
    "mpc": _mpc,
    "mpc-rti": _mpc_rti,
    "run": _folder("run", _run),
    "ppo": _folder("ppo", PPOPolicy),
    "sb3": _folder("sb3", SB3Policy),
    "torchppo": _folder("torchppo", _torch_ppo),
    "bc": _folder("bc", _bc),
    "zoo": _folder("zoo", ZooPolicy),
    "shield": _shield,
}
"""spec kind -> loader(env, ARG) of its policy (ARG: the text after the first colon, '' without one)"""


def parse_spec(spec: str) -> tuple[str, str]:
    """(kind, ARG) of a policy spec: a known kind before the first colon, else a bare folder
    (kind "run"); anything else is refused, naming the specs there are."""
    kind, _, arg = spec.partition(":")
    if kind in LOADERS:
        return kind, arg
    if spec and Path(spec).is_dir():
        return "run", spec
    raise UserError(f"unknown policy {spec!r}; use {POLICY_SPECS}")


def load_policy(spec: str, env):
    """The policy of a spec (the module's docstring) for ``env``: its kind's loader in LOADERS."""
    kind, arg = parse_spec(spec)
    return LOADERS[kind](env, arg)


def run_spec(run_dir: str | Path, shield: bool = False) -> str:
    """The spec of a finished run's policy (behind scara_gym.wrappers.Shield with ``shield``)."""
    return ("shield:" if shield else "") + f"run:{run_dir}"


def shipped_model(spec: str) -> Path | None:
    """The model folder of a ``ppo:NAME_OR_DIR`` spec (whose figures a shipped model is tested
    against), else None."""
    kind, arg = parse_spec(spec)
    return resolve_model(arg) if kind == "ppo" else None
