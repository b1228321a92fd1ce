"""CUDA kernels of the GPU vector environment: one thread per robot, running the compiled
per-robot step of `scara_gym.envs.core` (and through it the model's integrator and
dynamics) as device functions. There is one physics source: the kernels below only give
each thread its index and its work arrays, and report failures.

numba-cuda compiles the package's CPU-jitted functions for the device on first launch
(20-40 s). Under numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernels run as
Python, one thread at a time, and call the same functions compiled for the CPU, so that the
CUDA backend is tested bit for bit against the CPU vector environment on a machine without
a GPU.

Importing this module imports ``numba.cuda`` (the ``cuda`` install extra, numba-cuda).
"""

from __future__ import annotations

import numpy as np

if not hasattr(np, "row_stack"):  # numba-cuda 0.30 still calls np.row_stack, which numpy 2.4 removed
    np.row_stack = np.vstack

import numba  # noqa: E402
from numba import boolean, cuda, float64  # noqa: E402

from scara_gym.envs.core import begin_robot, vector_robot_step  # noqa: E402
from scara_gym.model.integrator import SMALL_SHAPE, STACK_SHAPE, WORK_SHAPE  # noqa: E402
from scara_gym.model.records import N_EVENTS  # noqa: E402

SIMULATOR = bool(numba.config.ENABLE_CUDASIM)
# flags the step kernel reports to the host (one small copy per step)
FLAG_FAILURES, FLAG_FIRST_FAILED, FLAG_PLANS_LEFT = 0, 1, 2
N_FLAGS = 3

if SIMULATOR:
    from numba.cuda.simulator.cudadrv.devicearray import FakeCUDAArray, FakeWithinKernelCUDAArray

    def native(array):
        """The simulator's array wrappers unwrapped: the CPU-compiled functions take numpy arrays."""
        while isinstance(array, FakeWithinKernelCUDAArray):
            array = array._item
        return array._ary if isinstance(array, FakeCUDAArray) else array
else:
    @cuda.jit(device=True, inline=True)
    def native(array):
        """On a GPU arrays pass to device functions as they are."""
        return array


@cuda.jit
def step_kernel(same_step, max_episode_steps, terminate_collisions, goal_threshold, actions, robots, params,
                params_flat, config, task, log, outcomes, obs, prev_done, plans, plan_params, varied_params, plans_made,
                episodes, reward, terminated, truncated, final_obs, info, statuses, flags):
    """vector_robot_step for robot i = the thread's index, in the thread's local work arrays."""
    i = cuda.grid(1)
    if i >= robots.shape[0]:
        return
    workspace = (cuda.local.array(WORK_SHAPE, float64), cuda.local.array(SMALL_SHAPE, float64),
                 cuda.local.array(STACK_SHAPE, float64), cuda.local.array(N_EVENTS, boolean))
    status = vector_robot_step(
        i, same_step, max_episode_steps, terminate_collisions, goal_threshold, native(actions), native(robots),
        native(params), native(params_flat), native(config), native(task), native(log), native(outcomes), native(obs),
        native(prev_done), native(plans), native(plan_params), varied_params, native(plans_made),
        native(episodes), native(reward), native(terminated), native(truncated), native(final_obs), native(info),
        workspace)
    statuses[i] = status
    if status < 0:
        cuda.atomic.add(flags, FLAG_FAILURES, 1)
        cuda.atomic.min(flags, FLAG_FIRST_FAILED, i)
    cuda.atomic.min(flags, FLAG_PLANS_LEFT, plans_made[i] - episodes[i])


@cuda.jit
def begin_kernel(mask, starts, targets, robots, params, config, task, outcomes, obs):
    """begin_robot for every robot where ``mask`` (the episodes that reset() starts)."""
    i = cuda.grid(1)
    if i >= robots.shape[0] or not mask[i]:
        return
    begin_robot(i, native(starts)[i], native(targets)[i], native(robots), native(params), native(config),
                native(task), native(outcomes), native(obs))


def step_kernel_ptx(cc: tuple[int, int] = (9, 0)) -> str:
    """The step kernel (then the begin kernel) compiled to PTX for compute capability ``cc``, without a GPU (NVVM only):
    a check that the device build of the physics compiles, and the input of ``ptxas -v`` for
    its register and stack figures. numba-cuda asks the current device for its compute
    capability when it compiles the device functions a kernel calls; here there may be none,
    so the question is answered with ``cc`` for the duration of the call.
    """
    from types import SimpleNamespace
    from unittest import mock

    from numba import types
    from numba.cuda import dispatcher

    from scara_gym.envs.core import INFO_FIELDS, N_PARAMS_FLOATS
    from scara_gym.envs.task import ScaraTask
    from scara_gym.model import records

    task = ScaraTask(num_robots=2)
    n, typeof = 2, numba.typeof
    floats = lambda *shape: typeof(np.zeros(shape))  # noqa: E731
    ints, flags = typeof(np.zeros(n, np.int64)), typeof(np.zeros(n, np.bool_))
    signature = (types.boolean, types.int64, types.boolean, types.float64, floats(n, 3), typeof(task.robots),
                 typeof(task.robot_params), floats(n, N_PARAMS_FLOATS), typeof(task.step_config), typeof(task.constants),
                 typeof(np.zeros((n, 1), records.EVENT)), typeof(task.outcomes), typeof(task.obs), flags,
                 floats(n, 1, 6), floats(n, 1, N_PARAMS_FLOATS), types.boolean, ints, ints, floats(n), flags, flags,
                 typeof(task.obs), floats(n, len(INFO_FIELDS)), ints, typeof(np.zeros(N_FLAGS, np.int64)))
    begin_signature = (flags, floats(n, 3), floats(n, 3), typeof(task.robots), typeof(task.robot_params),
                       typeof(task.step_config), typeof(task.constants), typeof(task.outcomes), typeof(task.obs))
    device = SimpleNamespace(compute_capability=cc)
    with mock.patch.object(dispatcher, "get_current_device", lambda: device):
        ptx, _ = cuda.compile_ptx(step_kernel.py_func, signature, cc=cc)
        begin_ptx, _ = cuda.compile_ptx(begin_kernel.py_func, begin_signature, cc=cc)
    return ptx + "\n" + begin_ptx
