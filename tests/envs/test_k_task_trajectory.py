"""The vector env of ``hyst_gym/HotCalibrateUnknownK-v0`` produces, at a fixed seed, the numbers it produced before
its speed work, bit for bit: observations, rewards, terminations and truncations, the grid posterior's estimate and
spread, and the PE integrand of the env's model bank, at every step of 20 sub-envs over 260 steps (time limits,
overheats and the restarts after them included), under the benchmark's random actions, the tuned open-loop sine and a
feedback hold side by side. ``data/k_task_trajectory.npz`` was recorded by :func:`trajectory` with the code of commit
0131604 (before the split bank passes of ``physics/hysteresis.py`` and the fused node-plant step of
``envs/kernels.py``, and the simulator's plants and model bank in threads of ``envs/core.py``). 20 sub-envs of 216
node plants are above posterior.SPLIT_MIN_NODES: on two cores the grid posterior steps in two threads."""

import pathlib

import numpy as np
import pytest

import hyst_gym  # noqa: F401
from hyst_gym.envs import core as core_module
from hyst_gym.envs import posterior as posterior_module
from hyst_gym.envs.suite_v2 import HotCalibrateUnknownKVectorEnv

RECORDING = pathlib.Path(__file__).resolve().parent / "data" / "k_task_trajectory.npz"
SUB_ENVS, STEPS, SEED = 20, 260, 7
#: the recorded arrays, each (STEPS, SUB_ENVS)[, ...]
KEYS = ("observation", "reward", "terminated", "truncated", "estimate", "spread", "pe_integrand")


def _inputs(observation, heat_column, t, rng):
    """The field commands of step ``t``: random actions (sub-envs 0-9), a sine of 40 + 40 kA/m at 0.5 Hz, out of
    phase (10-14), full field until the coil has used most of its heat margin, then off (15-19)."""
    field = rng.uniform(-1.0, 1.0, SUB_ENVS)
    phase = 2.0 * np.pi * 0.5 * 0.05 * t + np.arange(SUB_ENVS)
    field[10:15] = (0.4 + 0.4 * np.sin(phase))[10:15]
    field[15:] = np.where(observation[15:, heat_column] < 0.8, 1.0, 0.0)
    return field[:, None].astype(np.float32)


def trajectory(vector_env_class=HotCalibrateUnknownKVectorEnv) -> dict:
    """The recorded arrays (:data:`KEYS`) of the fixed-seed run of ``vector_env_class`` (the task's vector env)."""
    env = vector_env_class(SUB_ENVS)
    observation, _ = env.reset(seed=SEED)
    heat_column = env.kept_names.index("heat_used")
    rng = np.random.default_rng(SEED)
    record = {key: [] for key in KEYS}
    for t in range(STEPS):
        observation, reward, terminated, truncated, info = env.step(_inputs(observation, heat_column, t, rng))
        for key, value in (("observation", observation), ("reward", reward), ("terminated", terminated),
                           ("truncated", truncated), ("estimate", env.posterior.estimate()),
                           ("spread", env.posterior.spread()), ("pe_integrand", info["pe_integrand"])):
            record[key].append(np.array(value))
    return {key: np.stack(values) for key, values in record.items()}


@pytest.mark.parametrize("split", [False, True])
def test_the_k_task_reproduces_its_recorded_trajectory_bit_for_bit(split, monkeypatch):
    """``split``: the simulator's plants and model bank and the grid posterior's node plants step in two blocks of
    sub-envs in two threads (at 20 sub-envs the simulator's bank, 640 models, is below SPLIT_MIN_NODES)."""
    if split:
        for module in (core_module, posterior_module):
            monkeypatch.setattr(module, "SPLIT_MIN_NODES", 1)
            monkeypatch.setattr(module, "step_threads", lambda: 2)
    recorded = np.load(RECORDING)
    env = HotCalibrateUnknownKVectorEnv(SUB_ENVS)
    assert bool(env.sim._plant_blocks) == split and (len(env.posterior._blocks) == 2 or not split)
    got = trajectory()
    for key in KEYS:
        assert got[key].dtype == recorded[key].dtype, key
        np.testing.assert_array_equal(got[key], recorded[key], err_msg=key)  # says where they differ
        # and the bits: -0.0 and 0.0, or two NaNs, pass a comparison of values
        assert got[key].tobytes() == recorded[key].tobytes(), key
    # not vacuous: episodes ended by their time limit and by overheats, and the estimate moved
    assert recorded["truncated"].any() and recorded["terminated"].any()
    assert np.unique(recorded["estimate"]).size > STEPS
