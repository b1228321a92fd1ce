"""The CUDA backend of the vector env (scara_gym.envs.cuda_vector): bit for bit against the CPU
vector env on numba's CUDA simulator (in a subprocess: numba reads NUMBA_ENABLE_CUDASIM at
import), the errors without a GPU, and the step kernel compiled for a real GPU (to PTX, where
numba-cuda's NVVM is installed), which the simulator cannot check."""

import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest

CASES = Path(__file__).with_name("cuda_simulator_cases.py")


@pytest.mark.slow
def test_the_cuda_backend_on_the_simulator_is_the_cpu_env_bit_for_bit():
    pytest.importorskip("numba.cuda")
    pytest.importorskip("torch")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(CASES)],
                            env=env, capture_output=True, text=True, timeout=1200)
    assert result.returncode == 0, result.stdout[-6000:] + result.stderr[-3000:]
    assert " passed" in result.stdout and "skipped" not in result.stdout, result.stdout[-2000:]


def test_without_a_gpu_device_cuda_says_what_is_missing():
    import gymnasium as gym

    import scara_gym  # noqa: F401
    try:
        from numba import cuda
    except ImportError:  # numba-cuda not installed: the error names the extra
        with pytest.raises(ImportError, match=r"scara_gym\[cuda\]"):
            gym.make_vec("Scara-C11-v1", num_envs=2, vectorization_mode="vector_entry_point", device="cuda")
        return
    if numba.config.ENABLE_CUDASIM or cuda.is_available():
        pytest.skip("a GPU (or the simulator) is there")
    with pytest.raises((RuntimeError, ImportError), match="NUMBA_ENABLE_CUDASIM|scara_gym\\[cuda\\]"):
        gym.make_vec("Scara-C11-v1", num_envs=2, vectorization_mode="vector_entry_point", device="cuda")


@pytest.mark.slow
def test_the_step_kernel_compiles_for_a_gpu():
    """The simulator runs the CPU build of the physics; this compiles the device build (sm_90 PTX):
    an allocation, a slice assignment or an unaligned record in the step would fail here."""
    pytest.importorskip("numba.cuda")
    code = ("from numba.cuda.cudadrv.nvvm import NVVM; NVVM(); "  # fail fast where NVVM or NVRTC is missing
            "from numba.cuda.cudadrv.nvrtc import _get_nvrtc_version; _get_nvrtc_version(); "
            "from scara_gym.envs.cuda_kernels import step_kernel_ptx; ptx = step_kernel_ptx((9, 0)); "
            "assert '.entry' in ptx; print('PTX', len(ptx))")
    env = {key: value for key, value in os.environ.items() if key != "NUMBA_ENABLE_CUDASIM"}
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=1200)
    if any(error in result.stderr for error in ("NvvmSupportError", "DynamicLibNotFoundError", "NVVM")) \
            and "PTX" not in result.stdout:
        pytest.skip("numba-cuda's NVVM and NVRTC libraries are not installed (pip install 'scara_gym[cuda]')")
    assert result.returncode == 0 and "PTX" in result.stdout, result.stderr[-4000:]


def test_the_card_states_the_extra_arguments_and_their_defaults():
    import inspect
    import re

    from scara_gym.envs.cuda_vector import ScaraCudaVectorEnv

    card = ScaraCudaVectorEnv.__doc__
    rows = dict(re.findall(r"^\s*\| (\w+) \| [^|]+ \| (\S+) \|$", card, flags=re.M))
    rows.pop("argument")  # the header
    parameters = inspect.signature(ScaraCudaVectorEnv.__init__).parameters
    extra = {name: p.default for name, p in parameters.items()
             if name not in ("self", "num_envs", "max_episode_steps", "autoreset_mode", "config", "kwargs")}
    assert rows == {name: str(default) for name, default in extra.items()}
    for name in ("observation_noise", "action_delay", "action_rate_limit"):  # how each acts here is said
        assert name in card
