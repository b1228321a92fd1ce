"""The C11 model: parameters, record types, dynamics, integrator and simulator.

numpy and numba only: nothing here imports gymnasium or torch (a test reads the imports).

- `params`: the frozen parameter tree with units and ranges;
- `records`: the record types of the compiled core;
- `dynamics`: the model as pure compiled functions;
- `integrator`: Dormand-Prince 5(4) with located mode switches;
- `simulator`: `Simulator`, `Trajectory`, `Event`;
- `compilation`: JIT options and the source-keyed numba cache.
"""

from scara_gym.model import compilation  # noqa: F401  (cache locators before any compiled function)
from scara_gym.model.params import (
    DEFAULT_PARAMS,
    ArmParams,
    AxisParams,
    ObstacleParams,
    ScaraParams,
    TaskParams,
)
from scara_gym.model.simulator import Event, SimulationError, Simulator, Trajectory, start_state

__all__ = [
    "ArmParams", "AxisParams", "DEFAULT_PARAMS", "Event", "ObstacleParams", "ScaraParams",
    "SimulationError", "Simulator", "TaskParams", "Trajectory", "start_state",
]
