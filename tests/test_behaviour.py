"""Behaviour is unchanged by refactoring: digests of seeded rollouts of both environments in
both control modes, recorded on the code before the "One house" restructuring (0.1.0) for
Scara-C11-v0, at its registration for Scara-C11-v1 and at commit d8dd043 for Scara-C11-v2, and
the tables of ``scara-c11 reproduce`` (tests/benchmark/test_cli.py)."""

import hashlib

import gymnasium as gym
import numpy as np
import pytest

import scara_gym

pytestmark = pytest.mark.slow  # about 40 s: 22,000 environment steps

CONFIGS = {
    "pd": {"control_mode": "pd", "randomize_target": True},  # collisions
    "pd-free": {"control_mode": "pd", "obstacle": False},  # successes
    "voltage": {"control_mode": "voltage", "randomize_target": True, "collision": "penalty"},  # truncations
}
# sha256 of 2,000 steps of the single env and 4 x 500 steps of the vector env, recorded at
# commit e1f5cf0 (before the restructuring) with the functions below
RECORDED = {
    ("pd", "single"): "f88502d4188d93a5023f23449b2e06d474d62f2f038cd230d3c29fec22db2394",
    ("pd", "NextStep"): "271cf39ccbb735774cc052695e152a8e614cc276ada99dbb2f57a7c61444a377",
    ("pd", "SameStep"): "e8b8b51a19aa17b9716c00bdd123f39ce21c70bc362c2de7c00c5dd1a2334a92",
    ("pd-free", "single"): "9165dfe88c344aee34bd9648971c07d53ffadc08fa61998e34a4cc63c4f89bb4",
    ("pd-free", "NextStep"): "5b8d70488ade0907591e388c6d5358adea81995737a0f4e2663f849039d3d4bb",
    ("pd-free", "SameStep"): "779497290a3754333df0d5015d6e48deb375caaafe772753f9d2a1a7ba84cfcf",
    ("voltage", "single"): "9e2a34835a5bb30c7f91001118aa951414dcd3e1336d761c562802f255064d2c",
    ("voltage", "NextStep"): "90dcfb55440900fab6dbca77fe025ac10ffb5216ee5b025521aea4b135ea9455",
    ("voltage", "SameStep"): "51c6d260deca0e478cf97b0cf26186b87a8ea0356b8d3343b6543fd5b350b217",
}

# Scara-C11-v1 (exact switches, rtol 1e-6, atol 1e-8), 2,000 single-env steps, recorded when
# the id was registered (0.3.0): a later change of v1's behaviour needs a new id
RECORDED_V1 = {
    "pd": "1bab46552947034bb43bbec7a44f874caa9b6a8d9d526e31e9bdbc0b57328d6d",
    "pd-free": "e72968e732d957aeb84477a82eee038a1f5de1431b59665a75435c1a5d12be6a",
    "voltage": "ee540adc65830b4ce5d589f708fec46219c71bd4c2b37c38487c3c589643d248",
}

# Scara-C11-v2 (exact switches, rtol 1e-7, atol 1e-9), 2,000 single-env steps, recorded at commit
# d8dd043 (before the switch search was restructured): v2 is frozen like the older ids
RECORDED_V2 = {
    "pd": "d4893376ad5813cfa4c11c6d0d7483d0c4cb94e4e061f9dbea348fa463893b50",
    "pd-free": "58737df94d6116ee312039b59df1045cc5981ba2d4247c874c13c21155a0dfc9",
    "voltage": "bf0c28480e24fb39a43cd200667d106d852029c18fa587c0359d8686a5e3f554",
}


# the variants, 2,000 single-env steps per configuration: the -v0 ids recorded at commit dfe4f9e
# (before the variants' -v1 ids and the classes' new defaults), the -v1 ids at their registration
VARIANT_CONFIGS = {"pd": {"control_mode": "pd"}, "voltage": {"control_mode": "voltage", "collision": "penalty"}}
RECORDED_VARIANTS = {
    ("Scara-C11-RandomPhysics-v0", "pd"): "6a22d8091794601268c0ef819beb74de58af3baf4fd4d9a3ed14e773d4102411",
    ("Scara-C11-RandomPhysics-v0", "voltage"): "b29fbfee3069a9d39f7caae02e4aeb02eabb1bd6e64f308ff971baf770d464c2",
    ("Scara-C11-RandomWall-v0", "pd"): "7a2728f3157977e99d49ab94e76f9a27803b6ec6bef2d955f24be858ea591d80",
    ("Scara-C11-RandomWall-v0", "voltage"): "67f29ed2504a74d813bdfe495df4a5eda69277cf58cc1a06b981dc972b70ac08",
    ("Scara-C11-Goal-v0", "pd"): "b96a757ec52288fbf05fff280d0476798ee8d8a0dc82d05fbfee4e22425821f3",
    ("Scara-C11-Goal-v0", "voltage"): "4cf4fb66547c88cfdfdaa86c20ffac479bcbcd9ac3d990546ee4bb18176c762f",
    ("Scara-C11-RandomPhysics-v1", "pd"): "960a9289298d1f23f39c57b0a3f145584609621b4eb1dc3f9cc52d5d1385f56d",
    ("Scara-C11-RandomPhysics-v1", "voltage"): "afc2527c0ebcd19b29b47ab327cc9a89ad7221197d2e097b75e2b4d473d841f3",
    ("Scara-C11-RandomWall-v1", "pd"): "46866160892848cd4c3e3eccdab05593ecace64695916d72dfd9153529d16e17",
    ("Scara-C11-RandomWall-v1", "voltage"): "dffefd350b6df277cd9c0275660363bb3daa3f728f538b186083cb7617c9d50a",
    ("Scara-C11-Goal-v1", "pd"): "109398f7c83c7fa2ef074f207b44d893a353a06fd068edf093a2373014ff9b55",
    ("Scara-C11-Goal-v1", "voltage"): "1e2ce7cf538ed64255b1c8632e13f6357f9b293f4f645c6b6722711bd714d9cf",
}


def _feed(digest, value):
    """Every value as float64 bytes, dicts by sorted key: obs, rewards, flags and info."""
    if isinstance(value, dict):
        for key in sorted(value):
            digest.update(key.encode())
            _feed(digest, value[key])
    else:
        digest.update(np.ascontiguousarray(np.asarray(value, dtype=np.float64)).tobytes())


def _actions(rng, control_mode, n):
    if control_mode == "pd":  # the C11 target with occasional set-point kicks
        base = np.array([2 / np.pi, 2 / np.pi, 0.5])
        kicks = rng.random((n, 1)) < 0.05
        return base + rng.normal(0.0, 0.5, (n, 3)) * kicks
    return rng.uniform(-1.2, 1.2, (n, 3))  # beyond [-1, 1] too: clipping is counted


def single_env_digest(config, steps=2000, seed=0, env_id="Scara-C11-v0"):
    env = gym.make(gym.spec(env_id), **config)  # frozen ids on purpose: from the spec, not called out of date
    rng = np.random.default_rng(seed)
    digest = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    _feed(digest, obs), _feed(digest, info)
    for action in _actions(rng, config["control_mode"], steps):
        obs, reward, terminated, truncated, info = env.step(action)
        for value in (obs, reward, terminated, truncated, info):
            _feed(digest, value)
        if terminated or truncated:
            obs, info = env.reset()
            _feed(digest, obs), _feed(digest, info)
    return digest.hexdigest()


def vector_env_digest(config, autoreset_mode, num_envs=4, steps=500, seed=0):
    venv = gym.make_vec(gym.spec("Scara-C11-v0"), num_envs=num_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode=autoreset_mode, **config)
    rng = np.random.default_rng(seed)
    digest = hashlib.sha256()
    obs, info = venv.reset(seed=seed)
    _feed(digest, obs), _feed(digest, info)
    actions = _actions(rng, config["control_mode"], steps * num_envs).reshape(steps, num_envs, 3)
    for action in actions:
        for value in venv.step(action):
            _feed(digest, value)
    return digest.hexdigest()


@pytest.mark.parametrize("name", CONFIGS)
def test_single_env_rollouts_are_bit_identical_to_the_recorded_ones(name):
    assert single_env_digest(CONFIGS[name]) == RECORDED[(name, "single")]


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("name", CONFIGS)
def test_vector_env_rollouts_are_bit_identical_to_the_recorded_ones(name, autoreset_mode):
    assert vector_env_digest(CONFIGS[name], autoreset_mode) == RECORDED[(name, autoreset_mode)]


@pytest.mark.parametrize("name", CONFIGS)
def test_v1_rollouts_are_bit_identical_to_the_recorded_ones(name):
    assert single_env_digest(CONFIGS[name], env_id="Scara-C11-v1") == RECORDED_V1[name]


@pytest.mark.parametrize("name", CONFIGS)
def test_v2_rollouts_are_bit_identical_to_the_recorded_ones(name):
    assert single_env_digest(CONFIGS[name], env_id="Scara-C11-v2") == RECORDED_V2[name]


@pytest.mark.parametrize("env_id, name", sorted(RECORDED_VARIANTS))
def test_variant_rollouts_are_bit_identical_to_the_recorded_ones(env_id, name):
    assert single_env_digest(VARIANT_CONFIGS[name], env_id=env_id) == RECORDED_VARIANTS[(env_id, name)]


def test_every_registered_id_is_frozen_by_a_digest():
    frozen = {"Scara-C11-v0", "Scara-C11-v1", "Scara-C11-v2"} | {env_id for env_id, _ in RECORDED_VARIANTS}
    assert frozen == set(scara_gym.ENV_IDS)


def test_the_digest_sees_a_change():
    """The digest has teeth: a different reward weight changes it."""
    changed = dict(CONFIGS["pd-free"], reward_weights={"time": 10.000001})
    assert single_env_digest(changed, steps=200) != single_env_digest(CONFIGS["pd-free"], steps=200)
