"""Suite v2 task envs (issue 23): registration, prior, sensors, jumps, single == vector, errors."""

import gymnasium
import numpy as np
import pytest

import hyst_gym  # noqa: F401
from hyst_gym.envs.registration import ENV_IDS, SUITE_IDS, SUITE_V2_IDS
from hyst_gym.envs.suite_v2 import TASKS_V2
from hyst_gym.envs.tasks import TASKS, env_classes


def _vec(task_id, n, **kw):
    return gymnasium.make_vec(task_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)


def test_one_id_list_registers_every_task_with_its_kind_s_classes():
    """The registered suite ids are exactly the TaskSpecs' ids, each made by the classes of its kind."""
    assert SUITE_IDS + SUITE_V2_IDS == tuple(TASKS) and set(TASKS) <= set(ENV_IDS)
    for task_id, spec in TASKS.items():
        single, vector = env_classes(spec.kind)
        assert type(gymnasium.make(task_id).unwrapped) is single
        assert type(_vec(task_id, 2).unwrapped) is vector
        with pytest.raises(TypeError):  # frozen
            spec.config["dt"] = 1.0


def test_the_simulator_draws_the_priors_itself():
    """The k prior and the start-temperature shape are the simulator's constructor arguments: its own reset
    (no hook replaced on the instance) draws them, and a grid of start temperatures is one reset option."""
    from hyst_gym.envs.core import IDENTIFICATION, BatchSimulator
    from hyst_gym.envs.suite_v2 import K_PRIOR, task_config_v2

    config = task_config_v2("hyst_gym/HotCalibrate-v0")
    sim = BatchSimulator(config, IDENTIFICATION, 4, temperature_prior="raised_cosine", pinning_prior=K_PRIOR)
    assert "reset" not in vars(sim)
    for row in range(4):
        sim.set_generator(row, np.random.default_rng(row))
    sim.reset(np.arange(4))
    assert np.all((sim.pinning >= 320.0) & (sim.pinning <= 480.0)) and np.unique(sim.pinning).size == 4
    temperatures = np.array([280.0, 290.0, 300.0, 310.0])
    sim.reset(np.arange(4), {"initial_temperature": temperatures, "pinning_k": 350.0})
    assert np.array_equal(sim.temperature, temperatures) and np.array_equal(sim.ambient0, temperatures)
    assert np.allclose(sim.a_true, config.a_of(temperatures)) and np.all(sim.pinning == 350.0)
    with pytest.raises(ValueError, match="initial_temperature has 2 values for 4 rows"):
        sim.reset(np.arange(4), {"initial_temperature": temperatures[:2]})
    plain = BatchSimulator(config, IDENTIFICATION, 1)
    plain.set_generator(0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="unknown option"):  # k has no prior there
        plain.reset([0], {"pinning_k": 350.0})


def test_every_task_is_registered_and_documented():
    assert set(SUITE_V2_IDS) == {spec.id for spec in TASKS_V2}
    for task_id in SUITE_V2_IDS:
        doc = type(gymnasium.make(task_id).unwrapped).__doc__
        for section in ("## Description", "## Action Space", "## Observation Space", "## Rewards",
                        "## Starting State", "## Episode End", "## Arguments", "## Version History"):
            assert section in doc, (task_id, section)


def test_calibration_prior_is_the_raised_cosine():
    venv = _vec("hyst_gym/HotCalibrate-v0", 2000)
    venv.reset(seed=0)
    low, high = venv.unwrapped.config.initial_temperature_range
    x = (venv.unwrapped.sim.temperature - low) / (high - low)
    # raised cosine on [0, 1]: mean 1/2, variance 1/12 - 1/(2 pi^2) = 0.0327 (uniform: 0.0833)
    assert abs(x.mean() - 0.5) < 0.01
    assert abs(x.var() - (1 / 12 - 1 / (2 * np.pi ** 2))) < 0.003


def test_displacement_only_hides_the_velocity():
    env = gymnasium.make("hyst_gym/DisplacementOnly-v0", reporter="agent")
    assert env.unwrapped.observation_names == ["displacement", "field", "elapsed", "previous_estimate", "heat_used"]
    obs, _ = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape == (5,)
    full = env.unwrapped.sim.observation()[0]
    assert full.shape == (5,) and np.array_equal(obs[:4], full[[0, 2, 3, 4]]) and obs[4] == 0.0
    in_loop = gymnasium.make("hyst_gym/DisplacementOnly-v0")
    names = ["displacement", "field", "elapsed", "a_estimate", "estimate_spread", "heat_used"]
    assert in_loop.unwrapped.observation_names == names and in_loop.unwrapped.posterior.channels == [0]


def test_jump_moves_a_at_the_drawn_step():
    env = gymnasium.make("hyst_gym/DriftJump-v0").unwrapped
    env.reset(seed=5, options={"ambient_drift_rate": 0.0})
    step, change = int(env.jump_step[0]), float(env.jump_change[0])
    assert 40 <= step < 160 and 5 <= abs(change) <= 12
    a = []
    for _ in range(step + 2):
        a.append(env.step(np.zeros(1, dtype=np.float32))[4]["a_true"])
    slope = 7012.0 / 293.15
    assert abs(a[step] - a[step - 1] - slope * change) < 1.0      # the jump, within a step of cooling
    assert abs(a[step - 1] - a[step - 2]) < 0.5
    env.reset(seed=5, options={"jump_step": 7, "jump_change": -6.0})
    assert env.jump_step[0] == 7 and env.jump_change[0] == -6.0


@pytest.mark.parametrize("task_id", ["hyst_gym/DriftJump-v0", "hyst_gym/DisplacementOnly-v0",
                                     "hyst_gym/HotCalibrateUnknownK-v0"])
def test_single_equals_vector_and_is_deterministic(task_id):
    n, steps = 3, 120
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, n) + gymnasium.make(task_id).action_space.shape).astype(np.float32)
    venv = _vec(task_id, n)
    vobs, _ = venv.reset(seed=11)
    singles = [gymnasium.make(task_id) for _ in range(n)]
    sobs = [env.reset(seed=11 + i)[0] for i, env in enumerate(singles)]
    assert np.array_equal(vobs, np.array(sobs))
    if task_id.endswith("UnknownK-v0"):  # the same k per sub-env as its single twin
        assert np.array_equal(venv.unwrapped.k_true, [env.unwrapped.k_true[0] for env in singles])
    for t in range(steps):
        vobs, vrew, _, _, vinfo = venv.step(actions[t])
        for i, env in enumerate(singles):
            obs, reward, _, _, info = env.step(actions[t, i])
            assert np.array_equal(obs, vobs[i]) and reward == vrew[i] and info["a_true"] == vinfo["a_true"][i]


def test_bad_jump_option_is_one_error():
    env = gymnasium.make("hyst_gym/DriftJump-v0")
    with pytest.raises(ValueError, match="jump_step"):
        env.reset(seed=0, options={"jump_step": 0.5})
    with pytest.raises(ValueError, match="unknown suite task"):
        gymnasium.make("hyst_gym/DriftJump-v0", task="hyst_gym/Nope-v0")


@pytest.mark.parametrize("task_id", ["hyst_gym/DriftJump-v0", "hyst_gym/DisplacementOnly-v0"])
def test_sb3_adapter_trains_a_few_steps(task_id):
    """Stable-Baselines3 on the native vector env (SAME_STEP autoreset): episodes end and restart with the
    task's own observation size and a fresh jump."""
    from stable_baselines3 import PPO

    from hyst_gym.envs import make_sb3_vec_env

    venv = make_sb3_vec_env(task_id, num_envs=2, seed=0, episode_steps=30)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(128)
    assert venv.observation_space.shape == gymnasium.make(task_id).observation_space.shape


UNKNOWN_K = "hyst_gym/HotCalibrateUnknownK-v0"


def test_unknown_k_is_drawn_per_episode_from_its_prior_and_seeded():
    venv = _vec(UNKNOWN_K, 400)
    venv.reset(seed=0)
    k = venv.unwrapped.k_true
    # uniform over 320..480 A/m: mean 400, standard deviation 160/sqrt(12) = 46.2
    assert k.min() >= 320.0 and k.max() <= 480.0 and np.unique(k).size == k.size
    assert abs(k.mean() - 400.0) < 8.0 and abs(k.std() - 160 / np.sqrt(12)) < 5.0
    env = gymnasium.make(UNKNOWN_K)
    first = env.reset(seed=7)[1]["k_true"]
    second = env.reset()[1]["k_true"]
    assert first != second and env.reset(seed=7)[1]["k_true"] == first
    assert env.reset(seed=7, options={"pinning_k": 333.0})[1]["k_true"] == 333.0
    # the k-known task keeps the preset's k
    assert np.all(_vec("hyst_gym/HotCalibrate-v0", 4).unwrapped.k_true == 400.0)


def test_autoreset_draws_the_next_k_as_a_single_env_reset_does():
    env = gymnasium.make(UNKNOWN_K, episode_steps=5)
    env.reset(seed=3)
    for _ in range(5):
        env.step(np.zeros(1, dtype=np.float32))
    expected = env.reset()[1]["k_true"]
    venv = _vec(UNKNOWN_K, 1, episode_steps=5)
    venv.reset(seed=3)
    before = float(venv.unwrapped.k_true[0])
    for _ in range(6):  # 5 steps end the episode, the 6th resets it (NEXT_STEP)
        venv.step(np.zeros((1, 1), dtype=np.float32))
    assert float(venv.unwrapped.k_true[0]) == expected != before


def _outputs(k, field):
    """The noise-free normalized output along ``field`` (normalized commands) from the same start, with k."""
    env = gymnasium.make(UNKNOWN_K, output_noise=0.0, reporter="agent")
    env.reset(seed=1, options={"pinning_k": k, "initial_temperature": 293.15})
    return np.array([env.step(np.array([u, 0.0], dtype=np.float32))[0][0] for u in field])


def test_k_changes_the_loops_as_model_6_says():
    """A larger k (wider loops) lowers M while the field rises from the demagnetized state and raises it after
    the reversal; the same k gives the same output."""
    field = np.concatenate([np.linspace(0.025, 0.8, 32), np.full(8, 0.8), np.linspace(0.775, -0.6, 56)])
    low, high = _outputs(320.0, field), _outputs(480.0, field)
    assert np.array_equal(low, _outputs(320.0, field))
    rising, falling = slice(4, 32), slice(50, 96)
    assert np.all(high[rising] < low[rising]) and np.all(high[falling] > low[falling])
    # an order of magnitude above the sensor noise of the task (1e-4 of full scale)
    assert np.max(np.abs(high - low)) > 10 * gymnasium.make(UNKNOWN_K).unwrapped.config.output_noise


def test_unknown_k_passes_the_checkers_and_rejects_a_bad_k():
    import warnings

    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gymnasium.make(UNKNOWN_K).unwrapped)
        sb3_check_env(gymnasium.make(UNKNOWN_K).unwrapped)
    env = gymnasium.make(UNKNOWN_K)
    for bad in (-1.0, float("nan"), "400", True):
        with pytest.raises(ValueError, match="pinning_k"):
            env.reset(seed=0, options={"pinning_k": bad})
    from hyst_gym.envs.suite_v2 import PinningPrior

    with pytest.raises(ValueError, match="high"):
        PinningPrior(400.0, 300.0)
    with pytest.raises(ValueError, match="low"):
        PinningPrior(-1.0, 300.0)
    sim = env.unwrapped.sim
    for bad in (0.0, -5.0, float("inf")):
        with pytest.raises(ValueError, match="k must be"):
            sim.set_pinning([0], bad)
    sim.set_pinning([0], 350.0)
    assert sim.pinning[0] == 350.0 and env.unwrapped.k_true[0] == 350.0


def test_unknown_k_floor_is_the_k_known_bound_at_k_values_across_the_prior():
    """The floor's envelope is the largest over k values across the prior (the low end included), so it lies
    below the k-known task's, and the record says it ignores the k uncertainty."""
    from hyst_gym.envs.suite_v2 import calibration_floor

    known = calibration_floor("hyst_gym/HotCalibrate-v0")
    unknown = calibration_floor(UNKNOWN_K)
    assert unknown["kind"] == "bound" and 0 < unknown["value"] < known["value"]
    assert "ignores" not in known and "looser" in unknown["ignores"] and unknown["k_nodes"][0] == 320.0


CALIBRATION_IDS = [task for task in SUITE_V2_IDS if TASKS[task].calibrates]


def _episode_return_and_metric(env, actions, seed, options=None):
    """(return, the suite's per-draw metric from the infos as experiments.suite.common.play counts it)."""
    config, first = env.unwrapped.config, env.unwrapped.scored_from
    power = 2 if env.unwrapped.spec.id in CALIBRATION_IDS else 1
    env.reset(seed=seed, options=options)
    total, errors = 0.0, np.full(config.episode_steps, config.theta_width)
    for t, action in enumerate(actions):
        _, reward, terminated, truncated, info = env.step(action)
        total += reward
        errors[t] = abs(info["a_estimate"] - info["a_true"])
        if terminated or truncated:
            break
    return total, np.mean(errors[first:] ** power) / config.theta_width ** power, terminated


@pytest.mark.parametrize("task_id, reporter", [(task, "estimator") for task in CALIBRATION_IDS]
                         + [("hyst_gym/HotCalibrate-v0", "agent"), ("hyst_gym/DriftJump-v0", None)])
def test_the_reward_sums_to_the_score(task_id, reporter):
    """On random episodes, and on one that overheats (full field from a hot start), minus the return is the
    suite's per-draw metric in units of width(Theta) (squared on the calibration tasks): the scored window and
    width(Theta) for every scored step after an overheat."""
    env = gymnasium.make(task_id, **({} if reporter is None else {"reporter": reporter}))
    shape = env.action_space.shape
    rng = np.random.default_rng(3)
    for seed in (0, 1):
        total, metric, _ = _episode_return_and_metric(env, rng.uniform(-1, 1, (200,) + shape).astype(np.float32),
                                                      seed)
        assert total == pytest.approx(-metric, rel=1e-9, abs=1e-12)
    hot = {"initial_temperature": 318.15} if reporter is not None else {"initial_temperature": 318.15,
                                                                        "ambient_drift_rate": 0.0}
    total, metric, overheated = _episode_return_and_metric(env, np.ones((200,) + shape, dtype=np.float32), 2, hot)
    assert overheated and total == pytest.approx(-metric, rel=1e-9)


def test_the_estimator_in_the_loop_narrows_and_tracks_a():
    """The calibration env's estimator: the observation's spread shrinks from the prior's as data come in, and
    the estimate it reports (the scored one) ends within a few A/m of the truth under a moving field."""
    env = gymnasium.make("hyst_gym/HotCalibrate-v0")
    assert env.action_space.shape == (1,)
    obs, _ = env.reset(seed=4)
    names = env.unwrapped.observation_names
    width = env.unwrapped.config.theta_width
    prior_spread = obs[names.index("estimate_spread")]
    assert 0.02 < prior_spread < 0.2  # the raised-cosine prior over 40 K: about 9 K, 220 A/m
    for t in range(200):
        obs, _, terminated, _, info = env.step(np.array([0.6 * np.sin(0.3 * t)], dtype=np.float32))
        assert not terminated
    assert obs[names.index("estimate_spread")] < 0.05 * prior_spread
    assert abs(info["a_estimate"] - info["a_true"]) < 5.0
    estimate = env.unwrapped.config.theta_min + (obs[names.index("a_estimate")] + 1) / 2 * width
    assert estimate == pytest.approx(info["a_estimate"], abs=1e-3 * width)


def test_the_in_loop_vector_env_restarts_its_estimator_on_autoreset():
    """A sub-env reset automatically starts its estimator from the prior, as a single env's reset does: the
    vector env's observations and rewards equal single envs' over two episodes."""
    n, steps = 2, 12
    venv = _vec("hyst_gym/HotCalibrate-v0", n, episode_steps=5)
    singles = [gymnasium.make("hyst_gym/HotCalibrate-v0", episode_steps=5) for _ in range(n)]
    vobs, _ = venv.reset(seed=21)
    sobs = [env.reset(seed=21 + i)[0] for i, env in enumerate(singles)]
    assert np.array_equal(vobs, np.array(sobs))
    actions = np.random.default_rng(1).uniform(-1, 1, (steps, n, 1)).astype(np.float32)
    for t in range(steps):
        vobs, vrew, vterm, vtrunc, _ = venv.step(actions[t])
        for i, env in enumerate(singles):
            if t % 6 == 5:  # NEXT_STEP: the step after the 5th resets
                obs, _ = env.reset()
                assert vrew[i] == 0.0
            else:
                obs, reward, _, _, _ = env.step(actions[t, i])
                assert vrew[i] == pytest.approx(reward, rel=1e-12, abs=1e-15)
            assert np.array_equal(vobs[i], obs)


def _heat_trace(task_id, reporter, start, field):
    env = gymnasium.make(task_id, reporter=reporter)
    column = env.unwrapped.observation_names.index("heat_used")
    obs, _ = env.reset(seed=0, options={"initial_temperature": start})
    heat, temperature = [obs[column]], [env.unwrapped.sim.temperature[0]]
    for u in field:
        action = np.array([u] if reporter == "estimator" else [u, 0.0], dtype=np.float32)
        obs, _, terminated, _, info = env.step(action)
        heat.append(obs[column])
        temperature.append(info["temperature"])
        if terminated:
            break
    return np.array(heat), np.array(temperature), terminated


@pytest.mark.parametrize("task_id, reporter", [("hyst_gym/HotCalibrate-v0", "estimator"),
                                               ("hyst_gym/HotCalibrate-v0", "agent"),
                                               ("hyst_gym/DisplacementOnly-v0", "estimator"),
                                               (UNKNOWN_K, "estimator")])
def test_heat_used_is_the_rise_the_field_history_makes(task_id, reporter):
    """``heat_used`` is the coil's rise above its start over the hottest start's margin (15 K): the thermal model
    stepped from the applied field alone gives it, it is the same for every start temperature (so it says nothing
    about a), and it reaches 1 where the hottest start of the prior overheats."""
    from hyst_gym.envs.suite_v2 import heat_scale
    from hyst_gym.physics.thermal import mean_square_linear, temperature_step

    config = gymnasium.make(task_id).unwrapped.config
    scale, bound = heat_scale(config)
    assert scale == pytest.approx(1 / 15.0) and bound == pytest.approx(55.0 / 15.0)
    field = np.random.default_rng(5).uniform(-1, 1, 120)
    cold, _, _ = _heat_trace(task_id, reporter, 280.0, field)
    warm, temperature, _ = _heat_trace(task_id, reporter, 310.0, field)
    assert cold.size == warm.size == 121 and cold[0] == 0.0 and warm[-1] > 0.01
    np.testing.assert_allclose(cold, warm, rtol=1e-6, atol=1e-7)
    # the thermal model (tau*r' = -r + R_th*P, ambient = start) stepped over the applied field, independently
    thermal = config.thermal
    decay = np.exp(-config.dt / thermal.time_constant)
    applied, rise, expected = 0.0, 0.0, [0.0]
    for u in field:
        command = u * config.field_limit
        previous, applied = applied, min(max(command, applied - config.slew_rate_limit * config.dt),
                                         applied + config.slew_rate_limit * config.dt)
        offset = thermal.thermal_resistance * thermal.power_per_square_field * mean_square_linear(previous, applied)
        rise = float(temperature_step(rise, 0.0, 0.0, offset, decay))
        expected.append(rise * scale)
    np.testing.assert_allclose(warm, expected, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(warm, (temperature - 310.0) * scale, rtol=1e-6, atol=1e-7)
    hot, temperature, overheated = _heat_trace(task_id, reporter, 318.15, np.ones(200))
    assert overheated and temperature[-1] > config.temperature_limit and 1.0 <= hot[-1] < 1.1
    assert hot[-2] < 1.0  # the step before the overheat


def test_same_step_autoreset_keeps_the_finished_episode_s_heat():
    """SAME_STEP autoreset: the native calibration vector env equals a SyncVectorEnv of single envs step for
    step, the final observations (their heat_used from the finished episode's start) included, over episodes
    that end both by an overheat and by the time limit."""
    from gymnasium.vector import AutoresetMode, SyncVectorEnv

    task_id, n = "hyst_gym/HotCalibrate-v0", 4
    native = _vec(task_id, n, autoreset_mode=AutoresetMode.SAME_STEP, episode_steps=60)
    sync = SyncVectorEnv([lambda: gymnasium.make(task_id, episode_steps=60) for _ in range(n)],
                         autoreset_mode=AutoresetMode.SAME_STEP)
    np.testing.assert_array_equal(native.reset(seed=8)[0], sync.reset(seed=8)[0])
    actions = np.clip(np.random.default_rng(2).normal(0.9, 0.3, (150, n, 1)), -1, 1).astype(np.float32)
    ends = {"terminated": 0, "truncated": 0}
    for action in actions:
        out_n, out_s = native.step(action), sync.step(action)
        for a, b in zip(out_n[:4], out_s[:4]):
            np.testing.assert_array_equal(a, b)
        if "final_obs" in out_s[4]:
            for i in np.flatnonzero(out_s[4]["_final_obs"]):
                np.testing.assert_array_equal(out_n[4]["final_obs"][i], out_s[4]["final_obs"][i])
                assert out_n[4]["final_obs"][i][-1] > 0.0
        ends["terminated"] += int(out_s[2].sum())
        ends["truncated"] += int(out_s[3].sum())
    assert ends["terminated"] > 0 and ends["truncated"] > 0


@pytest.mark.parametrize("reporter", ["estimator", "agent"])
def test_heat_state_false_drops_only_the_heat_column(reporter):
    """The ablation ``heat_state=False``: the same episode, the observation without its last column, single and
    vector alike."""
    with_heat = gymnasium.make("hyst_gym/HotCalibrate-v0", reporter=reporter)
    without = gymnasium.make("hyst_gym/HotCalibrate-v0", reporter=reporter, heat_state=False)
    assert without.unwrapped.observation_names == with_heat.unwrapped.observation_names[:-1]
    assert without.observation_space.shape[0] == with_heat.observation_space.shape[0] - 1
    venv = _vec("hyst_gym/HotCalibrate-v0", 2, reporter=reporter, heat_state=False)
    a, b, v = with_heat.reset(seed=6)[0], without.reset(seed=6)[0], venv.reset(seed=6)[0]
    assert np.array_equal(a[:-1], b) and np.array_equal(v[0], b)
    actions = np.random.default_rng(0).uniform(-1, 1, (30,) + with_heat.action_space.shape).astype(np.float32)
    for action in actions:
        a, ra = with_heat.step(action)[:2]
        b, rb = without.step(action)[:2]
        v = venv.step(np.stack([action, action]))[0]
        assert np.array_equal(a[:-1], b) and ra == rb and np.array_equal(v[0], b)
