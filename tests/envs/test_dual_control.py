"""The dual-control task (hyst_gym/DualControl-v0): the plant inverse, the inverse controller's physics, the
reward that sums to the score, the overheat charge, single == vector, errors."""

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import hyst_gym  # noqa: F401
from task_vector_helpers import assert_single_is_sub_env
from hyst_gym.envs.dual_control import (DualControlEnv, DualControlVectorEnv, MILLING_REFERENCE, OVERHEAT_ERROR,
                                        MillingReference)

TASK = "hyst_gym/DualControl-v0"


def _episode(env, probe=0.0, seed=0, options=None):
    """Rewards and infos of one episode of a vector env (all sub-envs probing ``probe``)."""
    env.reset(seed=seed, options=options)
    env.start_a = env.sim.a_true.copy()
    rewards, infos = [], []
    for _ in range(env.config.episode_steps):
        _, reward, terminated, truncated, info = env.step(np.full((env.num_envs, 1), probe, dtype=np.float32))
        rewards.append(reward)
        infos.append(info)
        if np.any(terminated | truncated):
            break
    return np.array(rewards), infos


def test_the_reference_magnetization_inverts_the_first_order_plant():
    """Integrating y' = -lambda*y + nu*M_ref finely (independent RK4) follows the reference r once the plant's
    own transient (1/lambda = 10 ms) has died out; without the r'/lambda term it lags visibly."""
    decay = 100.0
    reference = MillingReference()
    dt, steps = 1e-4, 60_000
    y, worst, worst_static = 0.0, 0.0, 0.0
    y_static = 0.0
    for i in range(steps):
        t = i * dt

        def rhs(time, value, static=False):
            m = reference.output(time) if static else reference.magnetization(time, decay)
            return -decay * value + decay * float(m)  # y normalized by nu*Ms/lambda

        for name in ("y", "y_static"):
            value = y if name == "y" else y_static
            static = name == "y_static"
            k1 = rhs(t, value, static)
            k2 = rhs(t + dt / 2, value + dt / 2 * k1, static)
            k3 = rhs(t + dt / 2, value + dt / 2 * k2, static)
            k4 = rhs(t + dt, value + dt * k3, static)
            value = value + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            if static:
                y_static = value
            else:
                y = value
        if t > 0.1:
            r = float(reference.output(t + dt))
            worst = max(worst, abs(y - r))
            worst_static = max(worst_static, abs(y_static - r))
    assert worst < 1e-6 and worst_static > 1e-3


def test_with_the_true_a_the_controller_model_is_the_plant_and_tracks_better_than_a_wrong_a():
    """Fed the true a, the controller's model (6) moves exactly as the simulated magnetization (the same
    arithmetic); fed the nominal a it does not, and the tracking error is larger on every draw whose a is
    away from the nominal."""
    oracle = DualControlVectorEnv(8, TASK, controller_estimate="true")
    nominal = DualControlVectorEnv(8, TASK, controller_estimate="nominal")
    Ms = oracle.config.hysteresis.Ms
    scores = {}
    starts = {"initial_temperature": np.array([280.0, 285.0, 290.0, 295.0, 300.0, 308.0, 312.0, 316.0])}
    for name, env in (("oracle", oracle), ("nominal", nominal)):
        rewards, infos = _episode(env, seed=11, options=starts)
        scores[name] = -rewards.sum(axis=0)
        gap = np.abs(env._model_m - env.sim.magnetization).max()
        if name == "oracle":
            assert gap < 1e-9 * Ms
        else:
            assert gap > 1e-4 * Ms
    away = np.abs(nominal.start_a - oracle.config.initial_estimate) > 150.0
    assert np.array_equal(oracle.start_a, nominal.start_a) and away.sum() >= 6
    assert np.all(scores["oracle"][away] < scores["nominal"][away])


def test_the_posterior_learns_a_while_tracking_and_closes_most_of_the_gap():
    """With no probe the estimator identifies a from the tracking motion: the controller's estimate error
    shrinks, and the mean square tracking error lies between the oracle's and the nominal controller's."""
    seed, n = 5, 8
    results = {}
    for estimate in ("true", "posterior", "nominal"):
        rewards, infos = _episode(DualControlVectorEnv(n, TASK, controller_estimate=estimate), seed=seed)
        results[estimate] = (-rewards.sum(axis=0).mean(), infos)
    infos = results["posterior"][1]
    early = np.mean(np.abs(infos[0]["controller_estimate"] - infos[0]["a_true"]))
    late = np.mean(np.abs(infos[-1]["controller_estimate"] - infos[-1]["a_true"]))
    assert late < 0.3 * early
    assert results["true"][0] < results["posterior"][0] < results["nominal"][0]


def test_the_reward_sums_to_minus_the_mean_square_tracking_error():
    """The return is minus the mean over the 200 steps of the squared tracking error (% of y(Ms)); the error
    recomputed here from the noise-free plant state and the reference."""
    env = DualControlVectorEnv(3, TASK)
    env.reset(seed=2)
    total, squares = np.zeros(3), []
    sim = env.sim
    for step in range(200):
        probe = np.full((3, 1), 0.01 if step < 6 else 0.0, dtype=np.float32)
        _, reward, terminated, truncated, info = env.step(probe)
        total += reward
        y = (sim.state[:, sim.model.output_index] + sim.model.output_offset) / sim.scales[0]
        error = 100.0 * np.abs(y - MILLING_REFERENCE.output((step + 1) * env.config.dt))
        assert np.allclose(info["tracking_error"], error, rtol=0, atol=1e-12)
        squares.append(error ** 2)
    assert np.all(truncated) and not np.any(terminated)
    assert np.allclose(total, -np.mean(squares, axis=0), rtol=1e-12, atol=0)


def test_an_overheat_charges_every_step_left():
    env = DualControlVectorEnv(1, TASK)
    rewards, infos = _episode(env, probe=1.0, options={"initial_temperature": 330.0})
    steps = rewards.shape[0]
    assert steps < 200 and infos[-1]["temperature"][0] > env.config.temperature_limit
    tracked = np.array([info["tracking_error"][0] for info in infos])
    expected = -(np.sum(tracked ** 2) + (200 - steps) * OVERHEAT_ERROR ** 2) / 200
    assert rewards.sum() == pytest.approx(expected, rel=1e-12)


def test_single_env_is_the_vector_sub_env_and_passes_the_checker():
    assert_single_is_sub_env(TASK, DualControlEnv, seed=7, scale=0.02)


def test_bad_input_is_a_one_line_error():
    env = DualControlVectorEnv(1, TASK)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="must be a finite number in"):
        env.step(np.array([[2.0]]))
    with pytest.raises(ValueError, match="controller_estimate must be one of"):
        DualControlVectorEnv(1, TASK, controller_estimate="guess")
    with pytest.raises(ValueError, match="not a dual-control task"):
        DualControlVectorEnv(1, "hyst_gym/HotCalibrate-v0")
    with pytest.raises(ValueError, match="SAME_STEP is not supported"):
        DualControlVectorEnv(1, TASK, autoreset_mode=AutoresetMode.SAME_STEP)
    with pytest.raises(ValueError, match="transducer 'lumped' is not supported"):
        DualControlVectorEnv(1, TASK, transducer="lumped")
    with pytest.raises(ValueError, match="bias"):
        MillingReference(bias=0.9, amplitude=0.2)
