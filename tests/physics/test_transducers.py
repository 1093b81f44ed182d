"""Transducer models: exact discretization, lumped (12)/(13), the bias M0, batch layout."""

import math

import numpy as np
import pytest
import scipy.integrate
from hypothesis import given, settings
from hypothesis import strategies as st

from hyst_gym.physics import (DEFAULT_BIAS_MAGNETIZATION, FirstOrderPlant, LumpedLinear, LumpedNonlinear,
                              RodParams)
from hyst_gym.physics.linear_system import first_order_hold


def _ode_reference(A, b, drive_times, drive_values, t_end, sample_times, method="DOP853"):
    """Continuous solution with the drive linearly interpolated between samples (adaptive solver)."""
    def rhs(t, z):
        return A @ z + b * np.interp(t, drive_times, drive_values)
    # Integrate sample to sample so the solver never steps across a kink of the drive.
    z = np.zeros(A.shape[0])
    out = [z.copy()]
    for t0, t1 in zip(sample_times[:-1], sample_times[1:]):
        z = scipy.integrate.solve_ivp(rhs, (t0, t1), z, method=method, rtol=1e-11,
                                      atol=1e-14 * max(1.0, np.max(np.abs(z)))).y[:, -1]
        out.append(z.copy())
    return np.array(out)


def test_first_order_plant_matches_closed_form():
    plant = FirstOrderPlant(decay_rate=100.0, gain=1.0)
    dt = 1e-3
    model = plant.discretize(dt)
    # Constant M: y = nu*M/lambda*(1 - exp(-lambda t)); ramp M = r t: y = r nu (t/lam - (1-e^{-lam t})/lam^2).
    times = np.arange(0, 101) * dt
    step = model.simulate(np.full(times.size, 2.0e5))
    np.testing.assert_allclose(step, 2.0e5 / 100.0 * (1 - np.exp(-100.0 * times)), rtol=1e-12, atol=1e-12)
    ramp = model.simulate(3.0e7 * times)
    expected = 3.0e7 * (times / 100.0 - (1 - np.exp(-100.0 * times)) / 100.0 ** 2)
    np.testing.assert_allclose(ramp, expected, rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("factory", [LumpedLinear, LumpedNonlinear])
def test_lumped_discretization_is_exact_for_piecewise_linear_drive(factory):
    params = factory()
    dt = 2e-4   # coarser than a quarter of the 0.78 ms natural period
    model = params.discretize(dt)
    rng = np.random.default_rng(4)
    magnetization = np.cumsum(rng.normal(0, 1e5, 16))
    A, b = params.state_matrices()
    drive = model.drive_of(magnetization)
    times = np.arange(magnetization.size) * dt
    reference = _ode_reference(A, b, times, drive, times[-1], times)
    states = [model.initial_state(1)]
    for t in range(1, magnetization.size):
        states.append(model.advance(states[-1], magnetization[t - 1], magnetization[t]))
    states = np.concatenate(states)
    scale = np.max(np.abs(reference), axis=0)  # metres and metres per second
    assert np.all(np.max(np.abs(states - reference), axis=0) < 1e-8 * scale)


def test_paper_coefficients_and_the_bias():
    rod = RodParams()
    lumped = LumpedLinear()
    assert lumped.natural_frequency == pytest.approx(1275.7, abs=0.5)
    assert lumped.damping_ratio == pytest.approx(0.49, abs=0.005)
    # 150 um static displacement at M = 7e5 A/m (the rod data of RodParams, paper §2.2)
    static = lumped.discretize(1e-4).steady_state(7e5)[0, 0]
    assert static == pytest.approx(lumped.coupling * 7e5 / lumped.stiffness, rel=1e-12)
    assert static == pytest.approx(150e-6, rel=0.01)
    # rod data lump to the paper's chat, khat within 0.15 %
    assert rod.lumped_stiffness / rod.lumped_mass == pytest.approx(6.4251e7, rel=1.5e-3)
    assert rod.lumped_damping / rod.lumped_mass == pytest.approx(7.8899e3, rel=1.5e-3)
    # The bias that reproduces zetahat: 2*zeta*M0/m = 1.3724e-2  ->  M0 = 3.839e5 A/m
    m0 = rod.bias_magnetization()
    # independent hand computation from the raw rod data of RodParams (paper §2.2)
    mass = rod.ML + rod.rho * rod.A * rod.L / 3
    force_per_m2 = rod.Y * rod.A * 1.5 * rod.saturation_magnetostriction / rod.Ms ** 2
    assert m0 == pytest.approx(1.3724e-2 * mass / (2 * force_per_m2), rel=1e-12)
    assert m0 == pytest.approx(3.839e5, rel=1e-3)
    assert rod.gamma == pytest.approx(1.5e-3 / 7.65e5 ** 2, rel=1e-12)
    assert LumpedLinear.from_rod(rod).coupling == pytest.approx(1.3724e-2, rel=1e-12)


@given(st.floats(-5e4, 5e4), st.floats(-5e4, 5e4))
@settings(max_examples=25, deadline=None)
def test_nonlinear_model_linearizes_to_13_about_the_bias(offset_a, offset_b):
    nonlinear = LumpedNonlinear()
    linear = nonlinear.linearized(DEFAULT_BIAS_MAGNETIZATION)
    dt = 1e-4
    times = np.arange(200) * dt
    perturbation = offset_a * np.sin(2 * np.pi * 300 * times) + offset_b * np.sin(2 * np.pi * 1700 * times)
    magnetization = DEFAULT_BIAS_MAGNETIZATION + perturbation
    # Both start at the equilibrium of the bias.
    bias_nl = nonlinear.discretize(dt).steady_state(DEFAULT_BIAS_MAGNETIZATION)
    bias_l = linear.discretize(dt).steady_state(DEFAULT_BIAS_MAGNETIZATION)
    x_nl = nonlinear.discretize(dt).simulate(magnetization, state0=bias_nl)
    x_l = linear.discretize(dt).simulate(magnetization, state0=bias_l)
    offset = nonlinear.force_coefficient * DEFAULT_BIAS_MAGNETIZATION ** 2 / nonlinear.stiffness
    # (13) = (12) + zeta*M0^2/k, up to the neglected zeta*dM^2 term
    neglected = nonlinear.force_coefficient * np.max(perturbation ** 2) / nonlinear.stiffness * 3.0
    assert np.max(np.abs(x_l - (x_nl + offset))) <= neglected + 1e-15
    if max(abs(offset_a), abs(offset_b)) > 1e3:  # the linearization is only that good, not better
        assert np.max(np.abs(x_l - (x_nl + offset))) > 0


def test_batch_of_systems_matches_single_runs_and_layout():
    rng = np.random.default_rng(5)
    for params in (FirstOrderPlant(), LumpedLinear(), LumpedNonlinear()):
        model = params.discretize(1e-4)
        magnetization = rng.normal(0, 3e5, size=(50, 4))
        together = model.simulate(magnetization)
        assert together.shape == (50, 4)
        for i in range(4):
            np.testing.assert_allclose(together[:, i], model.simulate(magnetization[:, i]), rtol=1e-13, atol=1e-20)
        state = model.initial_state(4)
        assert state.shape == (4, model.state_size) and not state.any()
        out = model.advance(state, magnetization[0], magnetization[1])
        assert out.shape == state.shape and out is not state


def test_non_uniform_sampling_matches_uniform_and_continuous():
    params = LumpedLinear()
    rng = np.random.default_rng(6)
    times = np.cumsum(rng.uniform(0.5e-4, 1.5e-4, 20))
    times -= times[0]
    magnetization = 4e5 * np.sin(2 * np.pi * 900 * times)
    displacement = params.simulate(times, magnetization)
    A, b = params.state_matrices()
    reference = _ode_reference(A, b * params.coupling, times, magnetization, times[-1], times)[:, 0]
    np.testing.assert_allclose(displacement, reference, rtol=0, atol=1e-7 * np.max(np.abs(reference)))
    uniform = np.arange(30) * 1e-4
    np.testing.assert_allclose(params.simulate(uniform, 3e5 * np.cos(uniform * 5e3)),
                               params.discretize(1e-4).simulate(3e5 * np.cos(uniform * 5e3)), rtol=1e-12)


def test_discrete_models_are_stable_at_any_step():
    for params in (FirstOrderPlant(), LumpedLinear(), LumpedNonlinear(), LumpedLinear(damping=0.0)):
        for dt in (1e-6, 1e-4, 1e-2, 1.0):
            radius = np.max(np.abs(np.linalg.eigvals(params.discretize(dt).phi)))
            if params.damping_ratio if isinstance(params, LumpedLinear) else True:
                assert radius < 1.0
            else:  # undamped: on the unit circle, up to rounding of ~1e4 rad of rotation
                assert abs(radius - 1.0) < 1e-9


def test_first_order_hold_equals_augmented_exponential_identities():
    # Phi(2dt) = Phi(dt)^2 and the hold terms compose: two half steps equal one step
    # under a drive that is linear over the whole step.
    A = np.array([[0.0, 1.0], [-6.4e7, -7.9e3]])
    b = np.array([0.0, 1.0])
    phi1, g01, g11 = first_order_hold(A, b, 1e-4)
    phi2, g02, g12 = first_order_hold(A, b, 2e-4)
    np.testing.assert_allclose(phi1 @ phi1, phi2, rtol=1e-10, atol=1e-14)
    u0, u2 = 1.0, 3.0
    u1 = 0.5 * (u0 + u2)
    two_halves = phi1 @ (g01 * u0 + g11 * u1) + g01 * u1 + g11 * u2
    np.testing.assert_allclose(two_halves, g02 * u0 + g12 * u2, rtol=1e-10)


@pytest.mark.parametrize("make, message", [
    (lambda: FirstOrderPlant(decay_rate=0.0), "decay_rate must be a finite number > 0"),
    (lambda: FirstOrderPlant(gain=float("nan")), "gain must be finite"),
    (lambda: LumpedLinear(stiffness=-1.0), "stiffness must be a finite number > 0"),
    (lambda: LumpedLinear(damping=-1.0), "damping must be a finite number >= 0"),
    (lambda: LumpedNonlinear(mass=0.0), "mass must be a finite number > 0"),
    (lambda: RodParams(Y=float("inf")), "Y must be a finite number > 0"),
    (lambda: RodParams(cL=-2.0), "cL must be a finite number >= 0"),
    (lambda: LumpedLinear().discretize(0.0), "dt must be a finite number > 0"),
    (lambda: LumpedLinear().discretize(1e-4).initial_state(0), "n_systems must be >= 1"),
    (lambda: LumpedLinear().discretize(1e-4).advance(np.zeros((2, 3)), 0.0, 0.0), "state must have shape"),
    (lambda: LumpedLinear().simulate([0.0, 0.0], [1.0, 2.0]), "strictly increasing"),
    (lambda: LumpedLinear().simulate([0.0, 1.0], [1.0, float("nan")]), "magnetization must be finite"),
    (lambda: FirstOrderPlant().discretize(1e-3).velocity(np.zeros((1, 1))), "no velocity"),
])
def test_bad_input_raises_clear_errors(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_parameters_are_frozen():
    with pytest.raises(AttributeError):
        LumpedLinear().stiffness = 1.0
    model = LumpedLinear().discretize(1e-4)
    with pytest.raises(ValueError):
        model.phi[0, 0] = 2.0
    assert math.isclose(model.dt, 1e-4)
