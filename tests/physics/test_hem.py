"""The homogenized energy model: against an independent quadrature of its double integral, and its physics."""

import math

import numpy as np
import pytest
from scipy import integrate, stats

from hyst_gym.physics.hem import (HEMBatch, HEMParams, HEMState, advance_each, simulate_hem, simulate_hem_batch,
                                  state_with_magnetization, states_with_magnetization)

PARAMS = dict(relay_magnetization=3.0e5, reversible_susceptibility=40.0, coercive_median=20.0, coercive_spread=0.5,
              interaction_scale=25.0)


def relay_states(history, coercive, interaction):
    """Independent relay bookkeeping: the state of the relay (Hc, HI) after the sampled field ``history``
    (monotone between samples), started from the demagnetized state sign(HI) (the kernel's zero play
    outputs). The last sample at which H + HI reached +Hc or -Hc decides."""
    state = 1.0 if interaction > 0 else -1.0
    for h in history:
        if h + interaction >= coercive:
            state = 1.0
        elif h + interaction <= -coercive:
            state = -1.0
    return state


def hem_by_quadrature(history, p, density="normal"):
    """M (A/m) after ``history``: the HEM double integral over the lognormal coercive and the interaction
    densities, by adaptive scipy quadrature of the relay kernel (no play operator, no closed form)."""
    coercive_law = stats.lognorm(s=p["coercive_spread"], scale=p["coercive_median"])
    interaction_law = {"normal": stats.norm, "lorentzian": stats.cauchy,
                       "student_t2": lambda scale: stats.t(df=2, scale=scale)}[density](scale=p["interaction_scale"])
    history = np.asarray(history, float)

    def inner(hc):
        # the relay state is piecewise constant in HI, with jumps at Hc - h and -Hc - h and (the start) at 0
        jumps = sorted({float(hc - h) for h in history} | {float(-hc - h) for h in history} | {0.0})
        span = 1e4 * p["interaction_scale"]  # beyond it every relay is up (above) or down (below): equal tails cancel
        pieces = [-span] + [j for j in jumps if -span < j < span] + [span]
        total = 0.0
        for lo, hi in zip(pieces[:-1], pieces[1:]):
            if hi > lo:
                middle = 0.5 * (lo + hi)
                total += relay_states(history, hc, middle) * (interaction_law.cdf(hi) - interaction_law.cdf(lo))
        return total * coercive_law.pdf(hc)

    hi = coercive_law.ppf(1 - 1e-12)
    relay, _ = integrate.quad(inner, 0.0, hi, limit=400, epsabs=1e-10, points=[p["coercive_median"]])
    return p["reversible_susceptibility"] * history[-1] + p["relay_magnetization"] * relay


HISTORY = np.array([0.0, 35.0, 80.0, -20.0, -60.0, 10.0, 42.0, 5.0, 25.0])


@pytest.mark.parametrize("density", ["normal", "lorentzian", "student_t2"])
def test_kernel_matches_adaptive_quadrature_of_the_double_integral(density):
    params = dict(PARAMS, interaction_density=density)
    fine = simulate_hem(HISTORY, coercive_nodes=2000, **params)
    default = simulate_hem(HISTORY, **params)
    for t in (2, 4, 6, 8):
        reference = hem_by_quadrature(HISTORY[:t + 1], PARAMS, density)
        assert abs(fine[t] - reference) < 2e-5 * PARAMS["relay_magnetization"]
        # the default 16-node midpoint rule of the coercive integral
        assert abs(default[t] - reference) < 3e-3 * PARAMS["relay_magnetization"]


def test_coercive_rule_converges_at_second_order():
    reference = simulate_hem(HISTORY, coercive_nodes=4000, **PARAMS)
    errors = [np.max(np.abs(simulate_hem(HISTORY, coercive_nodes=n, **PARAMS) - reference)) for n in (16, 64)]
    assert errors[1] < errors[0] / 8  # 4x the nodes: at least 8x smaller (2nd order gives 16x)


def test_exact_for_any_monotone_path_no_substeps_needed():
    coarse = np.array([0.0, 90.0, -70.0, 30.0])
    fine = np.concatenate([np.linspace(a, b, 500, endpoint=False) for a, b in zip(coarse[:-1], coarse[1:])] + [[30.0]])
    m_coarse = simulate_hem(coarse, **PARAMS)
    m_fine = simulate_hem(fine, **PARAMS)
    assert m_fine[-1] == pytest.approx(m_coarse[-1], rel=1e-13)


def test_return_point_memory_wipes_out_the_inner_excursion():
    down = np.linspace(200.0, -15.0, 200)
    excursion = np.concatenate([np.linspace(-15.0, 30.0, 50), np.linspace(30.0, -5.0, 40), np.linspace(-5.0, 30.0, 40)])
    then = np.linspace(30.0, 120.0, 60)
    direct = simulate_hem(np.concatenate([down, np.linspace(-15.0, 30.0, 50), then]), **PARAMS)
    nested = simulate_hem(np.concatenate([down, excursion, then]), **PARAMS)
    # back at 30 A/m after the inner loop the state is the one before it, and so is every later sample
    np.testing.assert_allclose(nested[-60:], direct[-60:], rtol=1e-12, atol=1e-9)


def test_minor_loops_between_the_same_fields_are_congruent():
    loop = np.concatenate([np.linspace(-10.0, 25.0, 30), np.linspace(25.0, -10.0, 30)])
    first = simulate_hem(np.concatenate([np.linspace(0, 300.0, 50), np.linspace(300.0, -10.0, 50), loop]), **PARAMS)
    second = simulate_hem(np.concatenate([np.linspace(0, -300.0, 50), np.linspace(-300.0, 60.0, 50),
                                          np.linspace(60.0, -10.0, 30), loop]), **PARAMS)
    a, b = first[-60:], second[-60:]
    assert abs(a.mean() - b.mean()) > 1e-3 * PARAMS["relay_magnetization"]  # different histories, offset loops
    np.testing.assert_allclose(a - a[0], b - b[0], rtol=0, atol=1e-8 * PARAMS["relay_magnetization"])


def test_point_symmetric_and_saturating():
    field = np.concatenate([np.linspace(0, 400.0, 80), np.linspace(400.0, -400.0, 160),
                            np.linspace(-400.0, 400.0, 160)])
    up = simulate_hem(field, **PARAMS)
    down = simulate_hem(-field, **PARAMS)
    # to twice the compiled erf's absolute accuracy (1.5e-7) for the normal density
    np.testing.assert_allclose(down, -up, rtol=0, atol=3e-7 * PARAMS["relay_magnetization"])
    # far beyond every coercive and interaction field the relays are all up: only the reversible slope is left
    relay_part = simulate_hem(np.array([0.0, 1e6]), **PARAMS)[-1] - PARAMS["reversible_susceptibility"] * 1e6
    assert relay_part == pytest.approx(PARAMS["relay_magnetization"], rel=1e-9)
    # the descending branch lies above the ascending one (a loss, not a gain)
    asc, desc = up[240:], up[80:240][::-1]
    assert np.all(desc - asc[:160] >= -1e-6)


def test_small_loops_show_rayleigh_growth_of_permeability_and_loss():
    areas, permeabilities = [], []
    for h in (8.0, 16.0, 32.0):  # the lowest default node is at 4.2 A/m: below it loops are reversible
        cycle = np.concatenate([np.linspace(0, h, 20), np.linspace(h, -h, 40), np.linspace(-h, h, 40)])
        m = simulate_hem(np.concatenate([cycle, cycle[20:]]), **PARAMS)[-80:]
        H = np.concatenate([np.linspace(h, -h, 40), np.linspace(-h, h, 40)])
        areas.append(abs(np.trapezoid(m, H)))
        permeabilities.append(np.ptp(m) / (2 * h))
    # the secant permeability rises with the amplitude, the loss at least as fast as Rayleigh's h^3
    assert permeabilities[0] < permeabilities[1] < permeabilities[2]
    assert areas[1] >= 8 * areas[0] and areas[2] >= 8 * areas[1]


def test_bank_equals_single_models_and_each_layout_equals_shared():
    field = 60 * np.sin(np.linspace(0, 3 * np.pi, 300))
    params = [HEMParams(**dict(PARAMS, coercive_median=m)) for m in (10.0, 20.0, 35.0)]
    batch = HEMBatch.stack(params)
    bank = simulate_hem_batch(field, batch)
    for j, p in enumerate(params):
        np.testing.assert_array_equal(bank[:, j], simulate_hem(field, **{k: getattr(p, k) for k in PARAMS}))
    state, out = batch.demagnetized(), np.empty(batch.size)
    constants = batch.constants()
    for t, h in enumerate(field):
        advance_each(state, np.full(batch.size, h), constants, batch.kind, out)
        np.testing.assert_array_equal(out, bank[t])


def test_state_with_magnetization_starts_at_the_asked_magnetization():
    batch = HEMBatch.from_params(HEMParams(**PARAMS), 3)
    target = np.array([1.2e5, 0.0, -2.0e4])
    state = state_with_magnetization(batch, 5.0, target)
    m = simulate_hem_batch(np.array([5.0]), batch, state)[0]
    np.testing.assert_allclose(m, target, rtol=0, atol=1e-6 * PARAMS["relay_magnetization"])
    assert isinstance(state, HEMState)


def test_banks_solved_together_get_the_states_they_get_alone():
    """Banks of different sizes, fields, targets and reversible parts side by side: each state is the one
    its bank gets alone, bit for bit, and simulating from it starts at the asked magnetization."""
    rng = np.random.default_rng(3)
    batches = [HEMBatch(rng.uniform(5e5, 2e6, size), rng.uniform(0.1, 30.0, size), rng.uniform(50, 3e3, size),
                        rng.uniform(0.3, 1.5, size), rng.uniform(100, 8e3, size), "normal", 16,
                        np.full(size, saturation))
               for size, saturation in ((3, 0.0), (1, 5e3), (4, 2e4))]
    fields = np.array([3.0, -12.5, 0.4])
    targets = [2.0e4, -3.0e5, rng.uniform(-1e3, 1e3, 4)]
    states = states_with_magnetization([b.constants() for b in batches], batches[0].kind, fields, targets)
    for batch, field, target, state in zip(batches, fields, targets, states):
        alone = state_with_magnetization(batch, float(field), target)
        assert state.play.shape == alone.play.shape == (16, batch.size)
        np.testing.assert_array_equal(state.play, alone.play)
        m = simulate_hem_batch(np.array([field]), batch, state)[0]
        np.testing.assert_allclose(m, np.broadcast_to(target, (batch.size,)), rtol=0, atol=1.0)


def test_invalid_parameters_are_named():
    with pytest.raises(ValueError, match="coercive_spread"):
        HEMParams(coercive_spread=0.0)
    with pytest.raises(ValueError, match="interaction_density"):
        HEMParams(interaction_density="gumbel")
    with pytest.raises(ValueError, match="coercive_nodes"):
        HEMParams(coercive_nodes=0)
    assert math.isfinite(simulate_hem(np.array([0.0, 1.0]))[-1])


def test_compiled_erf_is_within_its_stated_accuracy():
    from hyst_gym.physics.hem import erf_inline

    x = np.linspace(-8.0, 8.0, 20001)
    errors = np.array([erf_inline(v) - math.erf(v) for v in x])
    assert np.max(np.abs(errors)) < 1.5e-7  # Abramowitz and Stegun 7.1.26


def test_compiled_atan_is_within_its_stated_accuracy():
    from hyst_gym.physics.hem import atan_inline

    x = np.concatenate([np.linspace(-50.0, 50.0, 20001), np.geomspace(1e-9, 1e12, 400), -np.geomspace(1e-9, 1e12, 400)])
    errors = np.array([atan_inline(v) - math.atan(v) for v in x])
    assert np.max(np.abs(errors)) < 1e-12


def test_saturating_reversible_part_changes_only_the_reversible_part():
    field = np.concatenate([np.linspace(0, 90.0, 40), np.linspace(90.0, -30.0, 60), np.linspace(-30.0, 50.0, 40)])
    linear = simulate_hem(field, **PARAMS)
    saturating = simulate_hem(field, reversible_saturation=25.0, **PARAMS)
    chi = PARAMS["reversible_susceptibility"]
    np.testing.assert_allclose(saturating - linear, chi * (25.0 * np.tanh(field / 25.0) - field), rtol=0,
                               atol=1e-9 * PARAMS["relay_magnetization"])
    # far out, the reversible part is bounded by chi*h_s instead of growing with H
    far = simulate_hem(np.array([0.0, 1e6]), reversible_saturation=25.0, **PARAMS)[-1]
    assert far == pytest.approx(PARAMS["relay_magnetization"] + chi * 25.0, rel=1e-9)


@pytest.mark.parametrize("density", ["normal", "lorentzian", "student_t2"])
def test_anhysteretic_population_adds_the_zero_coercivity_limit_and_nothing_else(density):
    field = np.concatenate([np.linspace(0, 90.0, 40), np.linspace(90.0, -30.0, 60), np.linspace(-30.0, 50.0, 40)])
    params = dict(PARAMS, interaction_density=density)
    plain = simulate_hem(field, **params)
    # weight 0 (the default) is the plain model bit for bit, whatever the scale
    np.testing.assert_array_equal(simulate_hem(field, anhysteretic_scale=7.0, **params), plain)
    with_population = simulate_hem(field, anhysteretic_magnetization=1.0e5, anhysteretic_scale=15.0, **params)
    # independently: the population's distribution function from scipy.stats, M_A*(2F(H) - 1)
    law = {"normal": stats.norm, "lorentzian": stats.cauchy,
           "student_t2": lambda scale: stats.t(df=2, scale=scale)}[density](scale=15.0)
    np.testing.assert_allclose(with_population - plain, 1.0e5 * (2 * law.cdf(field) - 1), rtol=0, atol=1.0)
    # it is the Hc -> 0 limit of a hysteretic population: a second HEM with a tiny coercive field
    limit = simulate_hem(field, relay_magnetization=1.0e5, reversible_susceptibility=0.0, coercive_median=1e-6,
                         coercive_spread=0.05, interaction_scale=15.0, interaction_density=density, coercive_nodes=1)
    np.testing.assert_allclose(with_population - plain, limit, rtol=0, atol=1.0)
    # still a Preisach model: return-point memory holds with the population
    excursion = np.array([0.0, 80.0, 10.0, 40.0, 25.0, 40.0, 10.0])
    m = simulate_hem(excursion, anhysteretic_magnetization=1.0e5, anhysteretic_scale=15.0, **params)
    assert m[-1] == pytest.approx(m[2], abs=1e-9 * PARAMS["relay_magnetization"])


def test_anhysteretic_population_in_banks_and_starts():
    params = [HEMParams(**PARAMS, anhysteretic_magnetization=w, anhysteretic_scale=s) for w, s in ((0.0, 1.0),
                                                                                                    (5e4, 10.0))]
    batch = HEMBatch.stack(params)
    field = np.array([0.0, 30.0, -12.0, 4.0])
    bank = simulate_hem_batch(field, batch)
    for j, p in enumerate(params):
        np.testing.assert_array_equal(bank[:, j], simulate_hem_batch(field, HEMBatch.from_params(p))[:, 0])
    target = np.array([9e4, -3e4])
    state = state_with_magnetization(batch, 5.0, target)
    np.testing.assert_allclose(simulate_hem_batch(np.array([5.0]), batch, state)[0], target, rtol=0,
                               atol=1e-6 * PARAMS["relay_magnetization"])
    with pytest.raises(ValueError, match="anhysteretic_magnetization"):
        HEMParams(anhysteretic_magnetization=-1.0)
    with pytest.raises(ValueError, match="anhysteretic_scale"):
        HEMParams(anhysteretic_scale=0.0)


def test_banks_mixing_the_options_equal_each_model_alone_bit_for_bit():
    """A bank runs only the stateless parts some model needs (hem.stateless_parts): a model alone takes the
    cheaper path of its own options, in a mixed bank the general one; both must give the same numbers."""
    from hyst_gym.physics.hem import (LINEAR_REVERSIBLE_ONLY, SATURATING_REVERSIBLE_PARTS,
                                      WITH_ANHYSTERETIC_POPULATION, stateless_parts)

    field = 70 * np.sin(np.linspace(0, 5 * np.pi, 400)) * np.linspace(1.0, 0.2, 400)
    for density in ("normal", "lorentzian", "student_t2"):
        params = [HEMParams(**PARAMS, interaction_density=density),
                  HEMParams(**PARAMS, interaction_density=density, reversible_saturation=30.0),
                  HEMParams(**PARAMS, interaction_density=density, anhysteretic_magnetization=4e4,
                            anhysteretic_scale=12.0)]
        alone = [HEMBatch.from_params(p) for p in params]
        assert [stateless_parts(b) for b in alone] == [LINEAR_REVERSIBLE_ONLY, SATURATING_REVERSIBLE_PARTS,
                                                        WITH_ANHYSTERETIC_POPULATION]
        for members in ((0, 1), (0, 2), (0, 1, 2)):
            batch = HEMBatch.stack([params[j] for j in members])
            bank = simulate_hem_batch(field, batch)
            state, out, constants = batch.demagnetized(), np.empty(batch.size), batch.constants()
            for column, j in enumerate(members):
                np.testing.assert_array_equal(bank[:, column], simulate_hem_batch(field, alone[j])[:, 0])
            for t, h in enumerate(field):
                advance_each(state, np.full(batch.size, h), constants, batch.kind, out)
                np.testing.assert_array_equal(out, bank[t])
