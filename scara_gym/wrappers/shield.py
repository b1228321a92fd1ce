"""A predictive safety shield with a committed backup, for any policy of the environment.

A shield (Alshiekh et al. 2018) stands between a policy and the robot and replaces an action
only where it could lead to a collision. This one is a predictive safety filter (Wabersich and
Zeilinger 2021) with a *committed* backup:

- The backup is the ``dec`` heuristic's braking move with a **fixed** set-point: hold axes 1
  and 2 at the joint angles the robot had before the step that was checked (the PD law brakes
  them, with the widened voltage near the wall) and drive axis 3 to its target, at least
  ``climb_margin`` above the highest wall of the models. The set-point is captured once and
  kept while the backup acts, so the backup is one fixed feedback law whose closed loop has
  an equilibrium, not a "hold where you are" that follows the arm as it drifts.
- Before each step the shield copies the robot's full state (``ScaraTask.snapshot``: the state
  vector, the current holds, the integrator's step size and the actuator line's delay and slew
  state) into its models, applies the policy's action there and then the backup, until every
  model has reached the **terminal set**: axes 1 and 2 within ``hold_tolerance`` of the held
  angles and every joint rate below ``rest_rate`` (the closed loop at rest at its set-point)
  for ``REST_STEPS`` steps in a row, the actuator line flushed (every action the policy gave
  applied, the delayed and slewed actions at the backup's), with the tip and the held angles'
  tip at least ``wall_margin`` from the wall's plane on the same side, or the tool that much
  above the wall. A model that touches the wall, or has not come to rest within ``horizon``
  steps, rejects the action.
- An accepted action's backup is committed: if the next action is rejected, the robot gets
  that backup, whose whole rollout to the terminal set was checked one step earlier. With an
  exact model the robot therefore never touches the wall: every state it reaches lies on a
  rollout that was certified to come to rest clear of it.

Models: the nominal parameters (``params``; None: the episode's own, an exact model) and, with
``robust`` (a `ParameterRanges` argument around them: a preset
name, a dict path -> (low, high) or a ParameterRanges), a certificate for every robot inside the
ranges, built in two parts (issue 53: finitely many modelled walls let the tool pass above or beyond
them and sink into a real wall between them):

- **The wall, by construction.** The obstacle's ranges (position, height, critical distance) are
  not modelled by samples: every model gets one *zone* (`wall_zone`), the band from the
  nearest wall's plane less the largest critical distance to the farthest one's plus it, up to the
  greatest height, ``wall_margin + dynamics_margin`` wider and higher. It holds the critical zone of
  every wall the ranges allow, so it holds every wall. A rollout is rejected the moment a model
  enters it (the integrator locates the critical switch; a model already inside rejects every
  action), approached from either side; at rest the tip and the held angles' tip lie beside the
  zone on the same side, or the tool above it. A certified rollout therefore never makes the
  robot critical: the widened voltage, the one way the wall enters the dynamics, never acts, and
  the wall's position and height drop out of the dynamics the models must cover.
- **The dynamics, by models and a margin.** The other ranges (masses, resistances, torque
  constants, current limits) are modelled by their ends (`range_ends`: every corner for up
  to three parameters, else each at either end, and the adverse corners where every parameter
  whose worse end is known sits at it at once: `ADVERSE_ENDS`) and ``robust_samples`` draws.
  These do not bound a robot between them exactly (a faster arm also brakes harder: no corner is
  the worst for every move), so the zone reaches ``dynamics_margin`` beyond the walls' critical
  zones: a robot between the models is certified wherever its tip's x and its tool's height stay
  within ``dynamics_margin`` of the range the models span at every instant of the rollout.

The certificate is therefore sound over the whole range under these **assumptions**, named, not
proved: (D) a robot inside the ranges stays within ``dynamics_margin`` (default 5 mm) of the
models' span along every rollout (measured with docs/scripts/shield_span.py: at most 4.1 mm in the
tip's x and 0.05 mm below in height, for 24 uniform draws at 94 certified states of 8 shielded
adversarial episodes: within the margin, with little to spare; docs/experiments.md); (S) the
backup's closed loop (PD on each axis) comes to rest at its set-point for every robot in the
ranges, as it does in the models, so the real robot ends where the held angles put its tip,
beside the zone (a geometric fact the terminal test checks); (E) the integrator finds a zone
entry: with ``exact_switches`` False (the default) a visit shorter than one integrator step (about
a millisecond) can go unseen, inside the margins; (L) the actuator line, control mode, tolerances
and control step are the environment's, and the shield reads the robot's true state. Outside the
ranges nothing is claimed. A target inside the zone cannot be reached behind the robust shield.
Without ``robust`` the models keep their own wall (exact with ``params=None``). The models share
the environment's actuator line (``action_delay``, ``action_rate_limit``), control mode,
tolerances and control step.

The shield reads the robot's true state from the environment, not from the (possibly noisy)
observation, and costs up to ``1 + horizon`` model steps per model and control step (a rollout
stops where every model is at rest).
"""

from __future__ import annotations

import numpy as np

from scara_gym.envs.randomization import ParameterRanges
from scara_gym.envs.task import OBSERVATION_LAYOUT, EpisodePlan, ScaraTask
from scara_gym.envs.vector import ScaraVectorEnv
from scara_gym.model import checks
from scara_gym.model.dynamics import tip_position
from scara_gym.model.params import DEFAULT_PARAMS, ScaraParams, resolve_params
from scara_gym.model.records import EV_CRITICAL_ON

Q, RATES, TARGET_ERROR = (OBSERVATION_LAYOUT[name] for name in ("q", "rate", "target_error"))
WALL_DISTANCE, HEIGHT_MARGIN = OBSERVATION_LAYOUT["wall_distance"], OBSERVATION_LAYOUT["height_margin"]
MAX_HORIZON = 1000      # [control steps]
MAX_ROBUST_SAMPLES = 256
REST_STEPS = 3          # consecutive steps at rest that end a rollout (not a turning point)
LINE_TOLERANCE = 1e-3   # [action units] a flushed actuator line: its actions this close to the backup's
DYNAMICS_MARGIN = 0.005  # [m] the robust zone's allowance for robots between the models (module docstring)


def hold_and_climb(held: np.ndarray, target: np.ndarray, lowest_height: float = -np.inf) -> np.ndarray:
    """The set-point that holds axes 1 and 2 at ``held`` [rad] and drives axis 3 to its target,
    at least ``lowest_height`` [m]: the braking move of the seed paper's obstacle rule (the
    ``dec`` heuristic's, and this shield's backup).
    """
    return np.array([held[0], held[1], max(target[2], lowest_height)])


MAX_CORNER_PATHS = 3
HIGH, LOW, EITHER = 1, 0, None
ADVERSE_ENDS = {"load_mass": HIGH, "link1_mass": HIGH, "link2_mass": HIGH, "resistance": HIGH,
                "current_limit": LOW, "height": HIGH, "torque_constant": EITHER, "x_position": EITHER}
"""per parameter (its path's last part): the end of its range where the backup brakes or climbs
worst: more mass, more resistance, less current, a higher wall. EITHER: no end is worse for
every motion (a torque constant gives torque per ampere and back-EMF alike; the nearer wall is
the one on the arm's side), so the adverse corners take both"""


def adverse_corners(ranges: ParameterRanges) -> list[dict]:
    """The corners of the ranges where every parameter of ADVERSE_ENDS sits at its worse end at
    once, one corner per choice of ends of the EITHER groups (all torque constants at one end
    together; the wall's position at either end). Parameters ADVERSE_ENDS does not name stay
    nominal.
    """
    fixed, groups = {}, {}
    for path, ends in ranges.ranges.items():
        leaf = path.rsplit(".", 1)[-1]
        if leaf not in ADVERSE_ENDS:
            continue
        if ADVERSE_ENDS[leaf] is EITHER:
            groups.setdefault(leaf, []).append(path)
        else:
            fixed[path] = ends[ADVERSE_ENDS[leaf]]  # HIGH, LOW: the index of that end
    corners = [fixed]
    for paths in groups.values():
        corners = [{**c, **{path: ranges.ranges[path][end] for path in paths}} for c in corners for end in (0, 1)]
    return corners if fixed or groups else []


WALL_LEAVES = ("x_position", "height", "critical_distance")
"""the obstacle's parameters: the robust shield covers their ranges by the zone (wall_zone), not by models"""


def wall_zone(walls, margin: float) -> dict[str, float]:
    """The obstacle overrides whose critical zone holds the critical zone of every wall in ``walls``
    (rows of x_position, height, critical_distance [m]: the corners of a box of walls) with
    ``margin`` [m] to spare: the band from the nearest wall's plane less the largest critical
    distance to the farthest one's plus it, up to the greatest height. A box of walls needs only
    its corners: a zone is the set |x - x_position| < critical_distance, height below the wall's,
    which grows with the distance and the height, and a band holds the planes between its ends.
    """
    walls = np.asarray(walls, dtype=np.float64).reshape(-1, 3)
    if not (np.all(np.isfinite(walls)) and np.isfinite(margin) and margin >= 0):
        raise ValueError(f"wall_zone: walls must be finite (x, height, critical distance) rows and margin >= 0, "
                         f"got {walls.tolist()!r} and {margin!r}")
    low, high = walls[:, 0].min(), walls[:, 0].max()
    return {"obstacle.x_position": 0.5 * (low + high),
            "obstacle.critical_distance": 0.5 * (high - low) + walls[:, 2].max() + margin,
            "obstacle.height": walls[:, 1].max() + margin}


def split_ranges(ranges: ParameterRanges) -> tuple[dict, dict]:
    """(the obstacle's ranges (WALL_LEAVES), the others'): the zone covers the first, models the second."""
    wall = {path: r for path, r in ranges.ranges.items() if path.startswith("obstacle.")}
    return wall, {path: r for path, r in ranges.ranges.items() if path not in wall}


def wall_corners(nominal: ScaraParams, wall_ranges: dict) -> list[tuple[float, float, float]]:
    """(x_position, height, critical_distance) of the nominal wall and of every corner of the
    obstacle's ranges (path -> (low, high); its other paths, the widened voltages, act only inside
    the critical zone, which a certified rollout never enters).
    """
    ends = [wall_ranges.get(f"obstacle.{leaf}", (getattr(nominal.obstacle, leaf),) * 2) for leaf in WALL_LEAVES]
    return [wall_row(nominal), *((x, h, d) for x in ends[0] for h in ends[1] for d in ends[2])]


def wall_row(params: ScaraParams) -> tuple[float, float, float]:
    """The wall of ``params`` as a row of wall_zone: (x_position, height, critical_distance) [m]."""
    return tuple(getattr(params.obstacle, leaf) for leaf in WALL_LEAVES)


def range_ends(ranges: ParameterRanges) -> list[dict]:
    """The robust shield's fixed models: every corner of the ranges (each path at either end)
    for up to MAX_CORNER_PATHS paths; else each path at either end with the others nominal, and
    the adverse corners (adverse_corners: the parameters that brake and climb worst, together).
    """
    paths = list(ranges.ranges)
    if len(paths) <= MAX_CORNER_PATHS:
        corners = [[]]
        for path in paths:
            corners = [c + [(path, end)] for c in corners for end in ranges.ranges[path]]
        return [dict(c) for c in corners]
    return [{path: end} for path in paths for end in ranges.ranges[path]] + adverse_corners(ranges)


class Shield:
    """``policy``'s action where every model certifies that the backup can still bring the arm
    to rest clear of the wall after it, else the committed backup's (module docstring).
    ``interventions`` counts the steps of the current episode where the backup acted. ``env``
    gives the models' configuration (``env.config``) and, for ``__call__``, the robot; ``filter``
    shields any env's robot with the same configuration (a vector environment's in training:
    shielded RL), with ``policy`` None. The env is read through its state surface only
    (``snapshot``, ``noise_free_observation``, ``setpoint_action``).

    Args:
        env (gymnasium.Env): the environment whose robot is shielded (its configuration makes the models).
        policy (callable | None): a callable obs -> action, or None for ``filter`` alone.
        params: the nominal model's parameters; None: the episode's own (an exact model).
        horizon: the most backup steps a rollout may take to come to rest.
        rest_rate: the joint rates below which the arm is at rest [rad/s, m/s].
        hold_tolerance: how close axes 1 and 2 must be to the held angles at rest [rad].
        wall_margin: the clearance from the wall's plane the terminal set keeps [m].
        climb_margin: how far above the highest wall the backup drives axis 3 [m].
        robust (str | dict | ParameterRanges | None): parameter ranges to certify the backup for as well (a preset name, a dict
            path -> (low, high) or a ParameterRanges); None: the nominal model only.
        robust_samples: parameter sets drawn from the ranges (the obstacle's aside: the zone covers them) beside their ends.
        robust_seed: the seed of those draws.
        dynamics_margin: how far beyond the walls' critical zones the robust zone reaches for robots
            between the models [m] (assumption D of the module docstring).
    """

    def __init__(self, env, policy, params: ScaraParams | None = DEFAULT_PARAMS, horizon: int = 200,
                 rest_rate: float = 0.02, hold_tolerance: float = 0.01, wall_margin: float = 0.005,
                 climb_margin: float = 0.01, robust=None, robust_samples: int = 8, robust_seed: int = 0,
                 dynamics_margin: float = DYNAMICS_MARGIN) -> None:
        self.env = env.unwrapped
        self.horizon = checks.integer("horizon", horizon, 1, MAX_HORIZON)
        for name, value in (("rest_rate", rest_rate), ("hold_tolerance", hold_tolerance),
                            ("wall_margin", wall_margin), ("climb_margin", climb_margin)):
            if not (checks.is_real(value) and np.isfinite(value) and 0 < value <= 1):
                raise ValueError(f"{name} must be a finite number in (0, 1], got {value!r}")
        self.dynamics_margin = checks.real("dynamics_margin", dynamics_margin, 0.0, 1.0, unit="m")
        self.rest_rate, self.hold_tolerance = float(rest_rate), float(hold_tolerance)
        self.wall_margin, self.climb_margin = float(wall_margin), float(climb_margin)
        if self.climb_margin < self.wall_margin:
            raise ValueError(f"climb_margin ({climb_margin!r} m) must be at least wall_margin ({wall_margin!r} m): the "
                             "backup climbs to where its terminal set counts the tool as above the wall")
        self.zone_margin = self.wall_margin + self.dynamics_margin
        """how far the robust shield's zone reaches beyond every wall's critical zone [m]"""
        self.policy = policy
        arguments = self.env.config.as_dict()
        nominal = arguments["params"] if params is None else params
        ranges = None
        if robust is not None:
            text = f"robust must be parameter ranges (a preset name, a dict or a ParameterRanges) or None, got {robust!r}"
            try:
                ranges = ParameterRanges.from_argument(robust, resolve_params(nominal))
            except (TypeError, ValueError, KeyError) as error:
                raise ValueError(f"{text}: {error}") from None
            if ranges is None:
                raise ValueError(text)
            robust_samples = checks.integer("robust_samples", robust_samples, 1, MAX_ROBUST_SAMPLES)
        wall_ranges, physics = split_ranges(ranges) if ranges is not None else ({}, {})
        physics = ParameterRanges(physics) if physics else None
        self.zone, self.walls = None, []
        """with robust: the obstacle overrides of every model (wall_zone over the nominal wall and the
        obstacle's ranges, wall_margin to spare): a rollout that enters the zone is rejected"""
        if ranges is not None:
            self.walls = wall_corners(resolve_params(nominal), wall_ranges)
            self.zone = wall_zone(self.walls, self.zone_margin)
        count = 1 + (len(range_ends(physics)) + robust_samples if physics is not None else 0)
        self.model_task = ScaraTask(**{**arguments, "params": nominal, "randomize_target": False,
                                       "randomize_params": physics if physics is not None else False,
                                       "observation_noise": None, "num_robots": count})
        task = self.model_task
        self.exact = params is None  # the first model takes each episode's own parameters
        self.model_params = [task.params]
        if physics is not None:
            rng = np.random.default_rng(checks.seed("robust_seed", robust_seed))
            self.model_params += [task.params.replace(v) for v in range_ends(physics)]
            self.model_params += [task.params.replace(physics.draw(rng)) for _ in range(robust_samples)]
        if self.zone is not None:
            self.model_params = [p.replace(self.zone) for p in self.model_params]
        self.params = task.params
        self.lowest_height = max(p.obstacle.height for p in self.model_params) + self.climb_margin
        self.name = f"{getattr(policy, 'name', 'policy')} + shield"
        self.interventions = 0
        self._episode = None        # (target, first model's parameters) the models' episodes hold for
        self._committed: dict = {}  # robot index -> the certified backup's set-point
        self._own = None            # (an episode's parameters, the exact model's: theirs with the zone)

    def reset(self) -> None:
        """Start an episode: the shielded policy's reset, no intervention counted, no committed backup."""
        if self.policy is not None:
            self.policy.reset()
        self.interventions = 0
        self._committed.clear()

    def backup_setpoint(self, snapshot: dict) -> np.ndarray:
        """The set-point the backup holds when it starts from the state of ``snapshot``."""
        return hold_and_climb(snapshot["x"][:3], snapshot["target"], self.lowest_height)

    def hold_distance(self, setpoint: np.ndarray, n: int) -> np.ndarray:
        """Per model (the first ``n``): the tip's x at the backup's held angles minus the wall's x."""
        p = self.model_task.robot_params[:n]
        hold_x = np.array([tip_position(setpoint[0], setpoint[1], setpoint[2], record)[0] for record in p])
        return hold_x - p["wall_x"]

    def at_rest(self, obs: np.ndarray, setpoint: np.ndarray, hold_distance: np.ndarray | None = None) -> np.ndarray:
        """Per model (rows of obs, in the models' order): at rest at the backup's ``setpoint``,
        clear of the wall (one step of the terminal test; certify also asks for REST_STEPS in a
        row and a flushed actuator line). ``hold_distance``: `hold_distance(setpoint, len(obs))`,
        which certify computes once per rollout rather than at every step.
        """
        p = self.model_task.robot_params[:len(obs)]
        still = np.all(np.abs(obs[:, RATES]) < self.rest_rate, axis=1)
        held = np.all(np.abs(obs[:, Q][:, :2] - setpoint[:2]) < self.hold_tolerance, axis=1)
        if hold_distance is None:
            hold_distance = self.hold_distance(setpoint, len(obs))  # where the held angles put the tip
        # beside the wall's plane, or with a zone beside the zone (whose width holds the margin)
        clearance = self.wall_margin if self.zone is None else p["critical_distance"]
        beside = (np.abs(obs[:, WALL_DISTANCE]) >= clearance) & (np.abs(hold_distance) >= clearance) \
            & (np.sign(hold_distance) == np.sign(obs[:, WALL_DISTANCE]))
        above = obs[:, HEIGHT_MARGIN] >= self.wall_margin
        return still & held & (beside | above)

    def _line_flushed(self, actions: np.ndarray) -> np.ndarray:
        """Per model: the actuator line holds and applies only the backup's ``actions`` (no
        action of the policy still waiting in it); True without a delay or rate limit.
        """
        line = self.model_task.actuator
        if line is None:
            return np.ones(len(actions), dtype=bool)
        flushed = np.all(np.abs(line.applied - actions) < LINE_TOLERANCE, axis=1)
        if line.pending.shape[1]:
            flushed &= np.all(np.abs(line.pending - actions[:, None, :]) < LINE_TOLERANCE, axis=(1, 2))
        return flushed

    def _entered_zone(self, active: np.ndarray) -> bool:
        """Whether an active model was inside its zone at any instant of its last step: critical at
        its end, or a critical switch located during it (the integrator's event log; a log that
        overflowed counts as entered).
        """
        robots, log = self.model_task.robots, self.model_task.log
        events = robots["n_events"]
        if np.any(robots["critical"][active] == 1) or np.any(events[active] > log.shape[1]):
            return True
        logged = np.arange(log.shape[1]) < events[:, None]
        return bool(np.any(((log["code"] == EV_CRITICAL_ON) & logged)[active]))

    def _begin(self, snapshot: dict) -> list:
        """The models' parameters for this snapshot, their episodes begun where the target or
        the exact model's parameters changed.
        """
        task = self.model_task
        own = snapshot["params"]
        if self.exact and self.zone is not None:  # the zone holds the episode's own wall as well
            if self._own is None or self._own[0] is not own:
                self._own = (own, own.replace(wall_zone([*self.walls, wall_row(own)], self.zone_margin)))
            own = self._own[1]
        params = [own, *self.model_params[1:]] if self.exact else self.model_params
        target = np.asarray(snapshot["target"], dtype=np.float64)
        if self._episode is None or not np.array_equal(self._episode[0], target) or (
                self._episode[1] is not params[0] and self._episode[1] != params[0]):
            for i, p in enumerate(params):
                task.begin_episode(i, EpisodePlan(task.default_start, target, p, {}))
            self._episode = (target.copy(), params[0])
        return params

    def certify(self, snapshot: dict, action: np.ndarray) -> bool:
        """Whether, in every model, ``action`` from ``snapshot`` and then the backup towards
        ``backup_setpoint(snapshot)`` leave the wall untouched and reach the terminal set (or
        the target) within the horizon.
        """
        task = self.model_task
        m = task.num_robots
        for i, p in enumerate(self._begin(snapshot)):
            task.restore(i, {**snapshot, "params": p})
        if self.zone is not None and np.any(task.robots["critical"] == 1):
            return False  # already inside the zone: nothing from here is certified
        setpoint = self.backup_setpoint(snapshot)
        hold_distance = self.hold_distance(setpoint, m)
        active = np.ones(m, dtype=bool)
        rested = np.zeros(m, dtype=int)
        actions = np.ascontiguousarray(np.tile(np.asarray(action, dtype=np.float64), (m, 1)))
        outcomes = task.outcomes
        for _ in range(self.horizon + 1):
            if m == 1:
                task.step_robot(0, actions[0])
            else:
                task.step_robots(active, actions, parallel=False)
            if np.any(outcomes["collisions"][active] > 0) or (self.zone is not None and self._entered_zone(active)):
                return False
            actions = np.ascontiguousarray(np.broadcast_to(
                task.setpoint_action(task.obs.astype(np.float64), setpoint), (m, 3)))
            rest = self.at_rest(task.obs, setpoint, hold_distance) & self._line_flushed(actions)
            rested = np.where(rest, rested + 1, 0)
            active &= ~(outcomes["reached"] | (rested >= REST_STEPS))
            if not active.any():
                return True
        return False

    def filter(self, env, index: int, action: np.ndarray) -> tuple[np.ndarray, bool]:
        """The shielded action of one robot.

        Args:
            env: a single environment (``index`` 0) or a CPU vector environment (robot ``index``),
                with this shield's configuration; read through its state surface (``snapshot``,
                ``noise_free_observation``, ``setpoint_action``).
            index: the robot's index.
            action: the action the policy chose for it.

        Returns:
            (the action the robot gets, whether the backup replaced ``action``). The committed
            backup is forgotten where a new episode starts (its first step).
        """
        action = np.asarray(action, dtype=np.float64)
        env = env.unwrapped
        vector = isinstance(env, ScaraVectorEnv)
        if not vector and index != 0:
            raise ValueError(f"Shield.filter: a single environment has robot 0 only, got index {index!r}")
        snapshot = env.snapshot(index) if vector else env.snapshot()
        if snapshot["episode_steps"] == 0 or index not in self._committed:
            self._committed[index] = self.backup_setpoint(snapshot)  # at rest at the start
        if self.certify(snapshot, action):
            self._committed[index] = self.backup_setpoint(snapshot)
            return action, False
        setpoint = self._committed[index]
        if vector:
            return env.setpoint_action(env.noise_free_observation(index).astype(np.float64), setpoint, index), True
        return env.setpoint_action(env.noise_free_observation().astype(np.float64), setpoint), True

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The shielded policy's action on obs, replaced by the backup's where it cannot be certified."""
        if self.policy is None:
            raise ValueError("Shield: no policy to shield (policy=None is for filter(), shielded training); give "
                             "Shield(env, policy) a policy to call it")
        action, replaced = self.filter(self.env, 0, self.policy(obs))
        self.interventions += replaced
        return action
