import numpy as np
import pytest
from scipy.integrate import solve_ivp

from baselines.agents import ScheduleAgent
from baselines.information import fisher_information, magnetization_sensitivity, plant_output
from baselines.schedules import (SCHEDULES, TUNING_GRIDS, ExcitationLimits, SchroederMultisine, apply_limits,
                                 grid_points, make_schedule)
from hyst_gym.physics import FirstOrderPlant

LIMITS = ExcitationLimits(field_max=1.2e5, slew_max=2.0e5, dt=0.01)


@pytest.mark.parametrize("name", sorted(TUNING_GRIDS))
def test_every_grid_point_obeys_the_common_limits(name):
    for params in grid_points(TUNING_GRIDS[name]):
        field = make_schedule(name, **params).sampled(700, LIMITS)
        steps = np.abs(np.diff(np.r_[0.0, field]))
        assert np.all(np.abs(field) <= LIMITS.field_max + 1e-9)
        assert np.all(steps <= LIMITS.max_field_change * (1 + 1e-12))


@pytest.mark.parametrize("name", sorted(SCHEDULES))
def test_schedules_are_pure_functions_of_time(name):
    schedule = make_schedule(name)
    t = np.linspace(0, 20, 333)
    np.testing.assert_array_equal(schedule.field(t), schedule.field(t.copy()))
    # evaluating a subset gives the same values: no hidden state
    np.testing.assert_array_equal(schedule.field(t)[100:], schedule.field(t[100:]))


def test_apply_limits_is_identity_inside_limits_and_rate_limits_steps():
    slow = 1e4 * np.sin(np.linspace(0, 3, 300))
    np.testing.assert_allclose(apply_limits(slow, LIMITS), slow)
    jumped = apply_limits(np.full(10, 1e5), LIMITS)
    np.testing.assert_allclose(jumped, np.minimum(LIMITS.max_field_change * np.arange(1, 11), 1e5))


def test_schroeder_phases_lower_the_crest_factor():
    t = np.linspace(0, 4, 8001)
    schroeder = SchroederMultisine(amplitude=1.0, base_frequency=0.25, n_harmonics=8)
    raw = schroeder._raw(t)
    zero_phase = np.sin(2 * np.pi * 0.25 * np.multiply.outer(t, np.arange(1, 9))).sum(-1)

    def crest(x):
        return np.max(np.abs(x)) / np.sqrt(np.mean(x ** 2))

    assert crest(raw) < 0.75 * crest(zero_phase)


def test_bad_schedule_names_and_limits():
    with pytest.raises(ValueError, match="unknown schedule"):
        make_schedule("square")
    with pytest.raises(ValueError, match="slew_max"):
        ExcitationLimits(slew_max=0.0)


def test_schedule_agent_follows_schedule_and_resets_per_env():
    agent = ScheduleAgent(make_schedule("ramp"), LIMITS, horizon_steps=50)
    expected = make_schedule("ramp").sampled(50, LIMITS) / LIMITS.field_max
    obs = np.zeros((2, 3))
    first = [agent.predict(obs)[0][:, 0] for _ in range(3)]
    np.testing.assert_allclose([f[0] for f in first], expected[:3], rtol=1e-6)
    actions, _ = agent.predict(obs, episode_start=np.array([True, False]))
    assert actions[0, 0] == pytest.approx(expected[0]) and actions[1, 0] == pytest.approx(expected[3])
    agent.reset(0)
    assert agent.act(np.zeros(3))[0] == pytest.approx(expected[0])
    assert agent.act(np.zeros(3))[0] == pytest.approx(expected[1])


def test_plant_filter_matches_ode_solution():
    plant, dt = FirstOrderPlant(), 0.01
    magnetization = 1e5 * np.sin(np.arange(60) * 0.3)
    y = plant_output(plant, magnetization, dt)
    sol = solve_ivp(lambda t, s: -plant.decay_rate * s + plant.gain * magnetization[min(int(t / dt), 59)],
                    (0, 59 * dt), [0.0], t_eval=np.arange(60) * dt, max_step=dt / 50, rtol=1e-10, atol=1e-6)
    np.testing.assert_allclose(y, sol.y[0], rtol=1e-4, atol=1e-3 * np.max(np.abs(y)))


def test_sensitivity_converges_in_the_difference_step():
    field = make_schedule("sine").sampled(200, LIMITS)
    coarse = magnetization_sensitivity(field, [7012.0], rel_step=4e-3)
    fine = magnetization_sensitivity(field, [7012.0], rel_step=1e-3)
    finer = magnetization_sensitivity(field, [7012.0], rel_step=2.5e-4)
    # central difference: error falls ~16x for a 4x smaller step
    assert np.max(np.abs(finer - fine)) < 0.25 * np.max(np.abs(fine - coarse)) + 1e-9
    assert np.max(np.abs(fine)) > 1.0  # M responds to a: dM/da is O(Ms/a) ~ 100


def test_no_excitation_carries_no_information():
    assert fisher_information(np.zeros(100), LIMITS.dt, [7012.0])[0] == 0.0
