"""Background kernels (hyst_gym/physics/background_compile.py): the plain-Python twins that serve the
first steps while a helper process compiles give the compiled kernels' numbers bit for bit, and the
helper's compiled code is what the environment runs afterwards."""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import gymnasium
import numpy as np
import pytest

from hyst_gym.physics import background_compile

HERE = pathlib.Path(__file__).resolve()
ROOT = HERE.parents[2]

#: (env id, number of sub-envs (0: the single env), steps): every kind of step kernel, the posterior's too
CASES = (("hyst_gym/Excitation-v0", 0, 300), ("hyst_gym/Estimation-v0", 0, 300),
         ("hyst_gym/Identification-v0", 0, 300), ("hyst_gym/Excitation-v0", 3, 60),
         ("hyst_gym/HotCalibrate-v0", 0, 40), ("hyst_gym/HotCalibrateUnknownK-v0", 2, 15),
         ("hyst_gym/DriftJump-v0", 0, 60), ("hyst_gym/DualControl-v0", 2, 30), ("hyst_gym/Discriminate-v0", 2, 30))


def trajectories(cases=CASES) -> dict:
    """Observations, rewards, ends and info numbers of seeded random-action runs, one array per case."""
    out = {}
    for env_id, n, steps in cases:
        env = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point") if n \
            else gymnasium.make(env_id)
        rng = np.random.default_rng(7)
        obs, info = env.reset(seed=11)
        rows = [np.ravel(obs)]
        for _ in range(steps):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * 0 +
                                                                 rng.uniform(-1, 1, env.action_space.shape))
            numbers = [np.ravel(np.asarray(info[key], dtype=float)) for key in sorted(info)
                       if np.asarray(info[key]).dtype.kind in "fiub"]
            rows.append(np.concatenate([np.ravel(obs), np.ravel(reward), np.ravel(terminated), np.ravel(truncated),
                                        *numbers]))
            if not n and (terminated or truncated):
                obs, info = env.reset()
        out[f"{env_id}/{n}"] = np.concatenate(rows).astype(np.float64)
    return out


#: run in a fresh interpreter: this module's trajectories (and numba's compile events) into the npz named by argv
CHILD = f"""
import importlib.util, sys
import numpy as np
from numba.core import event
compiled = []
class Count(event.Listener):
    def on_start(self, e): compiled.append(e.data["dispatcher"].py_func.__qualname__)
    def on_end(self, e): pass
event.register("numba:compile", Count())
spec = importlib.util.spec_from_file_location("background_case", {str(HERE)!r})
module = importlib.util.module_from_spec(spec); spec.loader.exec_module(module)
result = module.trajectories()
np.savez(sys.argv[1], compiled=np.array(compiled, dtype=str), **{{k.replace("/", "|"): v for k, v in result.items()}})
"""


def run_child(tmp_path, mode: str, extra_env=None):
    out = tmp_path / f"{mode}.npz"
    env = {**os.environ, background_compile.MODE_VARIABLE: mode, **(extra_env or {})}
    done = subprocess.run([sys.executable, "-c", CHILD, str(out)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    data = np.load(out)
    return {k.replace("|", "/"): data[k] for k in data.files if k != "compiled"}, list(data["compiled"]), done.stderr


def assert_same_bits(twin: dict, compiled: dict):
    assert twin.keys() == compiled.keys()
    for case in compiled:
        a, b = twin[case], compiled[case]
        assert a.shape == b.shape, case
        differ = np.flatnonzero(a.view(np.int64) != b.view(np.int64))
        assert differ.size == 0, f"{case}: {differ.size} of {a.size} numbers differ, first at {differ[:5]}: " \
                                 f"{a[differ[:3]]} vs {b[differ[:3]]}"


def test_python_twins_give_the_compiled_numbers_bit_for_bit_and_compile_nothing(tmp_path, monkeypatch):
    from hyst_gym.envs import discriminate, dual_control, kernels

    twin, compiled_names, _ = run_child(tmp_path, background_compile.PYTHON)
    assert compiled_names == [], f"the plain-Python path compiled {sorted(set(compiled_names))}"
    monkeypatch.setenv(background_compile.MODE_VARIABLE, background_compile.FOREGROUND)
    compiled = trajectories()  # this process: the compiled kernels
    entry_kernels = (kernels.excitation_step, kernels.identification_step, kernels.plant_step, kernels.finish_step,
                     kernels.posterior_step, kernels.posterior_vertex, dual_control.inverse_fields,
                     dual_control.advance_models, discriminate.advance_candidates, discriminate._trajectory_kernel)
    assert all(kernel.overloads for kernel in entry_kernels), "this process ran a kernel uncompiled"
    assert all(np.isfinite(v).any() and v.size > 100 for v in compiled.values())
    assert_same_bits(twin, compiled)


def test_the_twin_replaces_every_kernel_a_kernel_calls():
    from numba.core.dispatcher import Dispatcher

    from hyst_gym.envs import kernels

    twin = background_compile.python_twin(kernels.excitation_step)
    assert not isinstance(twin, Dispatcher) and twin.__code__ is kernels.excitation_step.py_func.__code__
    called = {name for name in twin.__code__.co_names if name in twin.__globals__}
    assert {"plant_step", "finish_step", "estimator_step", "field_commands"} <= called
    for name in called:
        assert not isinstance(twin.__globals__[name], Dispatcher), name
    # the module's own globals keep the compiled kernels
    assert isinstance(kernels.plant_step, Dispatcher)


def test_an_unknown_mode_is_one_line_naming_the_variable(monkeypatch):
    monkeypatch.setenv(background_compile.MODE_VARIABLE, "later")
    with pytest.raises(ValueError, match=r"^HYST_GYM_COMPILE='later' is not one of background, foreground, python$"):
        background_compile.compile_mode()


#: a fresh interpreter on an empty numba cache: the first step (twin, helper asked), then, once the helper
#: has answered, the compiled kernel loaded from its cache (not compiled here)
FIRST_STEPS = """
import json, sys, time
import gymnasium, numpy as np
from hyst_gym.envs import kernels
from hyst_gym.physics import background_compile
env = gymnasium.make("hyst_gym/Excitation-v0")
env.reset(seed=3)
actions = np.random.default_rng(5).uniform(-1, 1, (60, 1))
rows = [env.step(actions[0])[0]]
first = {"overloads": len(kernels.excitation_step.overloads),
         "requests": len(background_compile.helper_for_this_process().requests)}
answered = background_compile.wait_for_background_compiles(timeout=500)
rows += [env.step(a)[0] for a in actions[1:]]
print(json.dumps({**first, "answered": answered, "overloads_after": len(kernels.excitation_step.overloads),
                  "compiled_here": sum(kernels.excitation_step._cache_misses.values()),
                  "loaded": sum(kernels.excitation_step._cache_hits.values()),
                  "obs": np.concatenate(rows).astype(float).tolist()}))
"""


def test_the_helper_compiles_into_the_cache_and_the_env_then_runs_its_code(tmp_path):
    env = {**os.environ, background_compile.MODE_VARIABLE: background_compile.BACKGROUND,
           "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", FIRST_STEPS], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.splitlines()[-1])
    from hyst_gym.envs import kernels

    assert kernels.BACKGROUND_NOTICE in done.stderr
    assert result["overloads"] == 0 and result["requests"] >= 3  # the first step ran the twins
    assert result["answered"] and result["overloads_after"] == 1
    assert result["compiled_here"] == 0 and result["loaded"] == 1  # the helper's compiled code, from the cache
    assert any((tmp_path / "cache").rglob("*excitation_step*.nbc"))
    reference = gymnasium.make("hyst_gym/Excitation-v0")
    reference.reset(seed=3)
    actions = np.random.default_rng(5).uniform(-1, 1, (60, 1))
    expected = np.concatenate([reference.step(a)[0] for a in actions]).astype(float)
    assert np.array_equal(np.array(result["obs"]), expected)


def test_a_failed_background_compile_is_reported_with_its_reason():
    from types import SimpleNamespace

    helper = background_compile.CompileHelper()
    unknown = SimpleNamespace(py_func=SimpleNamespace(__module__="hyst_gym.no_such_module", __qualname__="kernel"))
    try:
        assert helper.request(unknown, ()) is background_compile.PENDING
        assert helper.wait(timeout=120)
        answer = helper.request(unknown, ())
    finally:
        helper.process.stdin.close()
        helper.process.wait(timeout=60)
    assert answer.startswith("the background compile failed (ModuleNotFoundError: No module named "
                             "'hyst_gym.no_such_module'")
    assert helper.process.returncode == 0  # stdin closed: the helper ends by itself
