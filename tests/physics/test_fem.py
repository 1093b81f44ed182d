"""The finite-element rod (10): against (13) at low frequency, convergence in N, resonances,
exact and stable discretization at the control step for N up to 256."""

import numpy as np
import pytest
import scipy.integrate
import scipy.sparse.linalg

from hyst_gym.physics import (DEFAULT_BIAS_MAGNETIZATION, FEMRod, LumpedLinear, LumpedNonlinear, RodParams,
                              analytic_frequencies)

ROD = RodParams()
M0 = DEFAULT_BIAS_MAGNETIZATION


@pytest.fixture(scope="module")
def fine_rod():
    """N = 256 linearized about the bias, discretized once for the module (dt = 2e-5 s)."""
    return FEMRod(ROD, 256, M0).discretize(2e-5)


@pytest.mark.parametrize("n_elements", [2, 256])
@pytest.mark.parametrize("frequency", [2.0, 100.0])
def test_fem_matches_lumped_13_at_low_frequency(n_elements, frequency):
    # The paper's Figure 4: FEM (10) linearized about (H0, M0) against (13), common M(t).
    dt = 1.0 / (500 * frequency)  # exact at any step; 500 samples per period
    times = np.arange(1501) * dt
    magnetization = 7e5 * np.sin(2 * np.pi * frequency * times)
    fem = FEMRod(ROD, n_elements, M0).discretize(dt).simulate(magnetization)
    paper = LumpedLinear().discretize(dt).simulate(magnetization)
    from_rod = LumpedLinear.from_rod(ROD).discretize(dt).simulate(magnetization)
    amplitude = np.max(np.abs(paper))
    assert amplitude == pytest.approx(1.5e-4, rel=0.02)
    # Within the 0.1 % by which the paper's fitted khat differs from the rod's K/m ...
    assert np.max(np.abs(fem - paper)) < 1.5e-3 * amplitude
    # ... and to (omega/omega_n)^2-level differences against (13) lumped from the same rod.
    assert np.max(np.abs(fem - from_rod)) < 5e-5 * amplitude


def test_quadratic_fem_matches_nonlinear_lumped_12_at_low_frequency():
    dt = 1e-4
    times = np.arange(1501) * dt
    magnetization = M0 + 3e5 * np.sin(2 * np.pi * 10 * times)
    fem_model = FEMRod(ROD, 16).discretize(dt)
    lumped_model = LumpedNonlinear.from_rod(ROD).discretize(dt)
    fem = fem_model.simulate(magnetization, state0=fem_model.steady_state(M0))
    lumped = lumped_model.simulate(magnetization, state0=lumped_model.steady_state(M0))
    assert np.max(np.abs(fem - lumped)) < 1e-5 * np.max(np.abs(lumped))
    static = ROD.force_coefficient * magnetization ** 2 / ROD.lumped_stiffness
    assert np.max(np.abs(fem - static)) < 1e-2 * np.max(static)


@pytest.mark.parametrize("drive", ["random", "step"])
def test_fem_response_converges_at_second_order_in_n(fine_rod, drive):
    dt = fine_rod.dt
    rng = np.random.default_rng(7)
    steps = 400
    if drive == "random":   # broadband: energy up to 25 kHz, past the third rod mode
        magnetization = np.cumsum(rng.normal(0, 3e4, steps))
    else:
        magnetization = np.r_[0.0, np.full(steps - 1, 3e5)]
    reference = fine_rod.simulate(magnetization)
    counts = [4, 8, 16, 32]
    errors = np.array([np.max(np.abs(FEMRod(ROD, n, M0).discretize(dt).simulate(magnetization) - reference))
                       for n in counts]) / np.max(np.abs(reference))
    orders = np.log2(errors[:-1] / errors[1:])
    assert np.all((orders > 1.9) & (orders < 2.1)), orders
    assert errors[-1] < 1e-5


def test_first_resonances_match_the_continuous_rod_with_tip_mass():
    exact = analytic_frequencies(ROD, 3)
    # sanity of the analytic solution: the first mode is the tip mass on the rod's spring,
    # the next ones are near those of a rod fixed at both ends (n*c/2L).
    assert exact[0] == pytest.approx(np.sqrt(ROD.lumped_stiffness / ROD.lumped_mass) / (2 * np.pi), rel=1e-3)
    assert exact[1] == pytest.approx(ROD.wave_speed / (2 * ROD.L), rel=0.05)
    fine = FEMRod(ROD, 256).natural_frequencies(3)
    np.testing.assert_allclose(fine, exact, rtol=3e-5)
    # Linear elements with consistent mass: frequency error O(h^2), from above.
    errors = np.array([FEMRod(ROD, n).natural_frequencies(3) / exact - 1 for n in (16, 32, 64)])
    assert np.all(errors > 0)
    np.testing.assert_allclose(errors[:-1] / errors[1:], 4.0, rtol=0.02)


def test_analytic_frequencies_of_a_free_rod_limit():
    # No tip mass or spring: a fixed-free rod, f_n = (2n-1)*c/(4L).
    rod = ROD.replace(ML=0.0, kL=0.0, cL=0.0)
    expected = np.array([1, 3, 5]) * rod.wave_speed / (4 * rod.L)
    np.testing.assert_allclose(analytic_frequencies(rod, 3), expected, rtol=1e-12)
    np.testing.assert_allclose(FEMRod(rod, 256).natural_frequencies(3), expected, rtol=1e-4)


def test_exact_discretization_against_stiff_solver():
    rod = FEMRod(ROD, 8, M0)
    dt = 1e-4
    model = rod.discretize(dt)
    rng = np.random.default_rng(8)
    magnetization = np.cumsum(rng.normal(0, 1e5, 12))
    times = np.arange(magnetization.size) * dt
    A, b = rod.state_matrices()
    drive = model.drive_of(magnetization)
    z = np.zeros(A.shape[0])
    expected = [0.0]
    for t0, t1 in zip(times[:-1], times[1:]):
        z = scipy.integrate.solve_ivp(lambda t, y: A @ y + b * np.interp(t, times, drive), (t0, t1), z,
                                      method="Radau", jac=A, rtol=1e-10, atol=1e-16).y[:, -1]
        expected.append(z[model.output_index])
    got = model.simulate(magnetization)
    assert np.max(np.abs(got - expected)) < 1e-7 * np.max(np.abs(expected))


def _spectral_radius_bound(phi, squarings=12):
    """Rigorous upper bound on the spectral radius: ||phi^(2^s)||_F^(1/2^s) (Gelfand)."""
    power, log_scale = phi.copy(), 0.0
    for _ in range(squarings):
        norm = np.linalg.norm(power)
        power /= norm  # keep the product representable; track the scale in logs
        log_scale = 2.0 * (log_scale + np.log(norm))
        power = power @ power
    return float(np.exp((log_scale + np.log(np.linalg.norm(power))) / 2 ** squarings))


@pytest.mark.parametrize("n_elements", [2, 256])
def test_discretization_is_stable_where_explicit_steps_are_not(n_elements):
    rod = FEMRod(ROD, n_elements)
    A = rod.state_matrices()[0]
    for dt in (1e-6, 1e-4):
        phi = rod.discretize(dt).phi
        assert np.all(np.isfinite(phi))
        assert _spectral_radius_bound(phi) < 1.0
    # The stiffest Kelvin-Voigt mode of the fine mesh decays at ~1e10 1/s. Classical RK4 is
    # stable only where |1 + z + z^2/2 + z^3/6 + z^4/24| <= 1 (z = lambda*dt), i.e. for
    # dt below ~2.8/|lambda|: it would need > 1e5 substeps per 1e-4 s control step.
    stiffest = scipy.sparse.linalg.eigs(A, k=1, which="LM", return_eigenvectors=False)[0]
    assert stiffest.real < 0
    z = stiffest * 1e-9
    rk4_growth = abs(1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24)
    if n_elements == 256:
        assert abs(stiffest) > 1e10
        assert rk4_growth > 1.0


def test_long_run_under_saturating_drive_stays_bounded(fine_rod):
    # 20,000 control steps of a full-amplitude square-ish drive: no growth, no NaN.
    magnetization = 7e5 * np.sign(np.sin(2 * np.pi * 500 * np.arange(20000) * fine_rod.dt))
    x = fine_rod.simulate(magnetization)
    assert np.all(np.isfinite(x))
    static = 2 * ROD.force_coefficient * M0 * 7e5 / ROD.lumped_stiffness
    assert np.max(np.abs(x)) < 2.0 * static


def test_batch_of_rods_matches_single_runs(fine_rod):
    rng = np.random.default_rng(9)
    magnetization = rng.normal(0, 2e5, size=(30, 3))
    together = fine_rod.simulate(magnetization)
    for i in range(3):
        np.testing.assert_allclose(together[:, i], fine_rod.simulate(magnetization[:, i]), rtol=1e-12, atol=1e-18)
    steady = fine_rod.steady_state([0.0, 7e5])
    assert steady.shape == (2, 512)
    assert fine_rod.output(steady)[1] == pytest.approx(2 * ROD.force_coefficient * M0 * 7e5 / ROD.lumped_stiffness,
                                                       rel=1e-9)
    assert fine_rod.velocity(steady)[1] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("kwargs, message", [
    ({"n_elements": 0}, "n_elements must be an integer"), ({"n_elements": 2.5}, "n_elements must be an integer"),
    ({"n_elements": 5000}, "n_elements must be an integer"), ({"rod": "terfenol"}, "rod must be a RodParams"),
    ({"bias_magnetization": float("nan")}, "bias_magnetization must be finite"),
])
def test_bad_rod_configuration_is_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        FEMRod(**kwargs)
