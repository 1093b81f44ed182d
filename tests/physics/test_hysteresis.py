"""The domain-wall model (6): consistency with (5), convergence order, physical sanity, layouts."""

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from hyst_gym import simulate_magnetization
from hyst_gym.physics import (DEFAULT_MAX_FIELD_STEP, HysteresisBatch, HysteresisParams, advance_each,
                              advance_shared, anhysteretic_magnetization, simulate_batch)

PAPER = dict(a=7012.0, k=400.0, alpha=-0.1, Ms=7.65e5, c=0.18)
HYSTERETIC = dict(a=7012.0, k=4000.0, alpha=-0.01, Ms=7.65e5, c=0.18)
SOFT = dict(a=5000.0, k=1500.0, alpha=-0.02, Ms=8.0e5, c=0.3)
SETS = {"paper": PAPER, "hysteretic": HYSTERETIC, "soft": SOFT}

#: turning points (A/m): a major loop, then nested minor loops; every leg is a multiple of
#: 800 A/m so that halving max_field_step exactly halves every substep
TURNING_POINTS = np.array([0, 1.2e5, -1.2e5, 1.2e5, -4e4, 2e4, -1.6e4, 6.4e4, -6.4e4, 1.6e3, 0.0])


# --------------------------------------------------------------------------- (5) against (6)

def _compose(field, irreversible, p, curve):
    """Solve M = (1-c)*Mirr + c*Man(H + alpha*M) for M (eq. 5); monotone in M."""
    def residual(m):
        man, _ = anhysteretic_magnetization(field + p["alpha"] * m, p["a"], p["Ms"], curve)
        return m - (1 - p["c"]) * irreversible - p["c"] * float(man)
    centre = (1 - p["c"]) * irreversible
    span = p["c"] * p["Ms"] * 1.001 + 1.0
    return scipy.optimize.brentq(residual, centre - span, centre + span, xtol=1e-9, rtol=1e-15)


def _integrate_form_5(turning_points, p, curve):
    """Integrate dMirr/dH = dhat*(Man - Mirr)/(k*delta - alpha*(Man - Mirr)) with an adaptive
    high-order solver and compose M by (5): an independent route to M at the turning points."""
    irreversible = 0.0
    out = [_compose(turning_points[0], irreversible, p, curve)]
    for start, end in zip(turning_points[:-1], turning_points[1:]):
        delta = math.copysign(1.0, end - start)

        def rhs(field, state, delta=delta):  # delta bound now: solve_ivp calls rhs within this leg only
            m = _compose(field, state[0], p, curve)
            man = float(anhysteretic_magnetization(field + p["alpha"] * m, p["a"], p["Ms"], curve)[0])
            gap = man - state[0]
            if gap * delta <= 0:  # dhat = 0
                return [0.0]
            return [gap / (p["k"] * delta - p["alpha"] * gap)]

        solution = scipy.integrate.solve_ivp(rhs, (start, end), [irreversible], method="DOP853",
                                             rtol=1e-11, atol=1e-6)
        irreversible = solution.y[0, -1]
        out.append(_compose(end, irreversible, p, curve))
    return np.array(out)


@pytest.mark.parametrize("name", ["paper", "hysteretic"])
@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_form_5_agrees_with_form_6_to_integration_error(name, curve):
    p = SETS[name]
    turning_points = TURNING_POINTS[:7]
    via_5 = _integrate_form_5(turning_points, p, curve)
    fine = simulate_magnetization(turning_points, max_field_step=6.25, anhysteretic=curve, **p)
    coarse = simulate_magnetization(turning_points, max_field_step=50.0, anhysteretic=curve, **p)
    integration_error = np.max(np.abs(coarse - fine))      # the scheme's error at step 50
    difference = np.max(np.abs(via_5 - fine))
    # (6) at step 6.25 is ~64x more accurate than at 50 (second order); the two routes must
    # agree to far better than the coarse error, and to 1e-7 Ms absolutely.
    assert difference < 0.1 * integration_error
    assert difference < 1e-7 * p["Ms"]
    assert np.max(np.abs(via_5)) > 0.5 * p["Ms"]  # the test reaches well into saturation


# --------------------------------------------------------------------------- convergence

def _errors(p, curve, steps, reference_step):
    reference = simulate_magnetization(TURNING_POINTS, max_field_step=reference_step, anhysteretic=curve, **p)
    return np.array([np.max(np.abs(simulate_magnetization(TURNING_POINTS, max_field_step=s, anhysteretic=curve,
                                                          **p) - reference)) / p["Ms"] for s in steps])


@pytest.mark.parametrize("name", ["hysteretic", "soft"])
@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_midpoint_scheme_is_second_order(name, curve):
    steps = [400.0, 200.0, 100.0, 50.0, 25.0]
    errors = _errors(SETS[name], curve, steps, reference_step=800 / 1024)
    orders = np.log2(errors[:-1] / errors[1:])
    assert np.all((orders > 1.9) & (orders < 2.15)), orders


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_paper_parameters_converge_at_second_order_on_average(curve):
    # With alpha*Ms/a = -11 the paper's set is stiff: M rides on Man and the switch dhat
    # flips near every reversal, so single halvings scatter; the fitted order is still ~2.
    steps = np.array([100.0, 50.0, 25.0, 12.5, 6.25, 3.125])
    errors = _errors(PAPER, curve, steps, reference_step=800 / 8192)
    order = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert 1.8 < order < 2.6, order


def test_default_step_error_is_as_documented():
    # DEFAULT_MAX_FIELD_STEP's docstring promises < 5e-6 Ms on the paper's set and
    # < 1e-6 Ms on the visibly hysteretic ones, against a 128x finer solution.
    for name, bound in (("paper", 5e-6), ("hysteretic", 1e-6), ("soft", 1e-6)):
        error = _errors(SETS[name], "ising", [DEFAULT_MAX_FIELD_STEP], DEFAULT_MAX_FIELD_STEP / 128)[0]
        assert error < bound, (name, error)


# --------------------------------------------------------------------------- physical sanity

parameter_sets = st.fixed_dictionaries({
    "a": st.floats(1e3, 3e4), "k": st.floats(50.0, 2e4), "alpha": st.floats(-0.3, 0.02),
    "Ms": st.floats(1e5, 2e6), "c": st.floats(0.0, 0.95), "anhysteretic": st.sampled_from(["ising", "langevin"]),
})
field_paths = st.lists(st.floats(-6e5, 6e5), min_size=1, max_size=8)


@given(parameter_sets, field_paths, st.floats(5.0, 200.0))
@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_magnetization_stays_below_saturation_and_never_decreases_against_the_field(p, turning, step):
    peak = p["Ms"] / p["a"] / (3.0 if p["anhysteretic"] == "langevin" else 1.0)
    assume(p["alpha"] * p["c"] * peak < 0.9)  # validation rejects the singular ones (tested below)
    # alpha*Man'(0) >= 1 is the mean-field instability: the anhysteretic curve of He = H + alpha*M has no single
    # stable branch (spontaneous magnetization), outside the model's physical range; with c = 0 validation does
    # not see it and the irreversible part runs away (hypothesis found alpha 0.0029, Ms 4.1e5, a 1000: M -> 8.9e6)
    assume(p["alpha"] * peak < 0.9)
    # Start demagnetized at H = 0 (M = Mirr = Man = 0). Starting at M = 0 under a large
    # field would imply |Mirr| > Ms by (5), a state outside the model's physical range.
    turning = [0.0] + turning
    field = np.concatenate([np.linspace(s, e, 7)[:-1] for s, e in zip(turning[:-1], turning[1:])] + [turning[-1:]])
    magnetization = simulate_magnetization(field, max_field_step=step, **p)
    assert np.all(np.isfinite(magnetization))
    # |M| < Ms; in deep saturation tanh rounds to exactly 1 and M may sit within
    # rounding (a few ulp) of Ms.
    assert np.all(np.abs(magnetization) <= p["Ms"] * (1 + 4 * np.finfo(float).eps))
    assert np.all(np.abs(magnetization[np.abs(field) < 2 * p["a"]]) < p["Ms"])
    # dM/dH >= 0 on every step of every branch (rising and falling).
    assert np.all(np.diff(magnetization) * np.sign(np.diff(field)) >= -1e-9 * p["Ms"])


@pytest.mark.parametrize("name", ["paper", "hysteretic", "soft"])
@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_major_loop_closes_after_first_cycle_and_is_point_symmetric(name, curve):
    p = SETS[name]
    peak = 4e5
    half = peak * np.sin(np.linspace(-np.pi / 2, np.pi / 2, 801))  # -peak .. +peak
    rising = np.concatenate([np.linspace(0, -peak, 401), half[1:]])  # initial curve to -peak, then up
    cycle = np.concatenate([-half[1:], half[1:]])                 # down then up: one full loop
    field = np.concatenate([rising, cycle, cycle])
    magnetization = simulate_magnetization(field, anhysteretic=curve, **p)
    n = cycle.size
    second, third = magnetization[-2 * n:-n], magnetization[-n:]
    assert np.max(np.abs(second - third)) < 1e-9 * p["Ms"]         # closed after the first cycle
    descending, ascending = third[:n // 2], third[n // 2:]
    assert np.max(np.abs(descending + ascending)) < 1e-9 * p["Ms"]  # M(-H) = -M(H) across branches
    remanence = np.abs(third[np.argmin(np.abs(cycle))])
    assert remanence > 0  # a real loop, not a line


@pytest.mark.parametrize("name", ["paper", "hysteretic", "soft"])
def test_reversal_is_reversible_until_magnetization_meets_anhysteretic(name):
    p = SETS[name]
    step = 2.0
    up = np.linspace(0, 8e4, 401)
    down = np.linspace(8e4, -8e4, 8001)[1:]
    field = np.concatenate([up, down])
    magnetization = simulate_magnetization(field, max_field_step=step, **p)
    man, _ = anhysteretic_magnetization(field + p["alpha"] * magnetization, p["a"], p["Ms"])
    irreversible = (magnetization - p["c"] * man) / (1 - p["c"])   # Mirr by (5)
    after = slice(up.size - 1, None)
    # Rising, M lags below Man; after the reversal Man falls faster than M until they meet.
    gap = (man - magnetization)[after]
    meets = int(np.argmax(gap <= 0))
    assert gap[0] > 0 and meets > 10, "the reversal must start with a reversible stretch"
    stretch = irreversible[after][:meets]
    # Purely reversible: Mirr is frozen (to integration error) until M meets Man ...
    assert np.max(np.abs(stretch - stretch[0])) < 1e-6 * p["Ms"]
    # ... and then it moves (the irreversible term switches on).
    later = irreversible[after][meets:]
    assert np.max(np.abs(later - stretch[0])) > 1e-2 * p["Ms"]


def test_positive_alpha_guard_keeps_susceptibility_non_negative():
    # alpha > 0 can put the denominator k*delta - alphahat*(Man - M) on the wrong side of delta.
    p = dict(a=2000.0, k=100.0, alpha=0.02, Ms=1.6e6, c=0.05)
    field = np.concatenate([np.linspace(0, 3e5, 301), np.linspace(3e5, -3e5, 601)[1:]])
    magnetization = simulate_magnetization(field, max_field_step=200.0, **p)
    assert np.all(np.isfinite(magnetization))
    assert np.all(np.diff(magnetization) * np.sign(np.diff(field)) >= 0)


# --------------------------------------------------------------------------- validation

@pytest.mark.parametrize("change, message", [
    ({"a": 0.0}, "a must be > 0"), ({"a": -1.0}, "a must be > 0"), ({"k": 0.0}, "k must be > 0"),
    ({"Ms": -5.0}, "Ms must be > 0"), ({"c": 1.0}, "0 <= c < 1"), ({"c": -0.1}, "0 <= c < 1"),
    ({"alpha": float("nan")}, "alpha must be finite"), ({"alpha": float("inf")}, "alpha must be finite"),
    ({"a": float("nan")}, "a must be finite"),
    ({"alpha": 0.06}, "denominator"),  # 0.06*0.18*765000/7012 = 1.18 >= 1
    ({"anhysteretic": "preisach"}, "anhysteretic must be one of"),
])
def test_bad_parameters_raise_clear_errors(change, message):
    with pytest.raises(ValueError, match=message):
        HysteresisParams(**change)
    with pytest.raises(ValueError, match=message):
        simulate_magnetization(np.zeros(3), **change)


def test_langevin_singularity_bound_is_three_times_wider():
    HysteresisParams(alpha=0.15, anhysteretic="langevin")  # 0.15*0.18*109/3 = 0.98 < 1
    with pytest.raises(ValueError, match="x3 for Langevin"):
        HysteresisParams(alpha=0.2, anhysteretic="langevin")


def test_bad_field_and_step_are_rejected():
    with pytest.raises(ValueError, match=r"field\[2\]"):
        simulate_magnetization([0.0, 1.0, float("nan")])
    with pytest.raises(ValueError, match="1-D"):
        simulate_magnetization(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="max_field_step"):
        simulate_magnetization([0.0, 1.0], max_field_step=0.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        simulate_magnetization([0.0, 1.0], time=[1.0, 1.0])
    with pytest.raises(TypeError, match="unknown parameter"):
        simulate_magnetization([0.0, 1.0], b=3.0)


# --------------------------------------------------------------------------- batch layouts

def _random_bank(seed, size=19):  # 19 = two 8-wide SIMD blocks and a scalar remainder
    rng = np.random.default_rng(seed)
    return [HysteresisParams(a=rng.uniform(5e3, 9e3), k=rng.uniform(300, 5e3), alpha=rng.uniform(-0.1, 0.0),
                             Ms=rng.uniform(6e5, 9e5), c=rng.uniform(0.05, 0.5)) for _ in range(size)]


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_shared_bank_matches_single_model_runs(curve):
    params = [p.replace(anhysteretic=curve) for p in _random_bank(1)]
    field = 1.5e5 * np.sin(np.linspace(0, 5 * np.pi, 701)) * np.linspace(0.3, 1.0, 701)
    bank = simulate_batch(field, HysteresisBatch.stack(params))
    for i, p in enumerate(params):
        single = simulate_magnetization(field, a=p.a, k=p.k, alpha=p.alpha, Ms=p.Ms, c=p.c, anhysteretic=curve)
        # bit for bit: SIMD lanes and the scalar remainder use the same IEEE arithmetic
        np.testing.assert_array_equal(bank[:, i], single)


def test_advance_shared_and_advance_each_agree_with_single_runs():
    params = _random_bank(2)
    batch = HysteresisBatch.stack(params)
    rng = np.random.default_rng(3)
    fields = np.cumsum(rng.normal(0, 2e4, size=(120, batch.size)), axis=0)  # one random walk per model
    fields[0] = 0.0
    state = np.zeros(batch.size)
    substeps = 0
    for t in range(1, fields.shape[0]):
        substeps += advance_each(state, fields[t - 1], fields[t], batch.a, batch.k, batch.alpha, batch.Ms,
                                 batch.c, batch.kind, DEFAULT_MAX_FIELD_STEP)
    expected_substeps = np.sum(np.maximum(1, np.ceil(np.abs(np.diff(fields, axis=0)) / DEFAULT_MAX_FIELD_STEP)))
    assert substeps == expected_substeps
    for i, p in enumerate(params):
        single = simulate_magnetization(fields[:, i], a=p.a, k=p.k, alpha=p.alpha, Ms=p.Ms, c=p.c)
        assert state[i] == single[-1]
    # shared layout under model 0's field, one step at a time, equals the trajectory function
    shared = np.zeros(batch.size)
    for t in range(1, fields.shape[0]):
        advance_shared(shared, fields[t - 1, 0], fields[t, 0], batch.a, batch.k, batch.alpha, batch.Ms,
                       batch.c, batch.kind, DEFAULT_MAX_FIELD_STEP)
    np.testing.assert_array_equal(shared, simulate_batch(fields[:, 0], batch)[-1])


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_the_bank_passes_give_the_one_model_midpoint_step_bit_for_bit(curve):
    """advance_shared steps a bank in passes over its models (the curve, the half step, the curve, the full step);
    advance_one holds one model's midpoint step in one expression chain: the same numbers, for both curves and for
    banks with and without a remainder after the SIMD blocks."""
    from hyst_gym.physics.hysteresis import advance_one

    for size in (1, 7, 19, 200):
        params = _random_bank(size, size)
        batch = HysteresisBatch.stack([p.replace(anhysteretic=curve) for p in params])
        kind = batch.kind
        fields = np.concatenate([[0.0], np.cumsum(np.random.default_rng(size).normal(0, 4e4, 60))])
        shared, single = np.zeros(batch.size), np.zeros(batch.size)
        for h0, h1 in zip(fields[:-1], fields[1:]):
            advance_shared(shared, h0, h1, batch.a, batch.k, batch.alpha, batch.Ms, batch.c, kind, 625.0)
            for b in range(batch.size):
                single[b] = advance_one(single[b], h0, h1, batch.a[b], batch.k[b], batch.alpha[b], batch.Ms[b],
                                        batch.c[b], kind, 625.0)[0]
            assert shared.tobytes() == single.tobytes(), (size, h0, h1)


# --------------------------------------------------------------------------- small-loop extension

from hyst_gym.physics.hysteresis import advance_shared_small_loop  # noqa: E402


def test_small_loop_kernel_with_zero_chi_r_is_model_6_bit_for_bit():
    """The extension's kernel with chi_r = 0 takes the same substeps with the same arithmetic."""
    field = np.concatenate([np.linspace(0, 1.2e5, 300), np.linspace(1.2e5, -3e4, 200), np.linspace(-3e4, 2e4, 50)])
    for curve in ("ising", "langevin"):
        batch = HysteresisBatch.stack([HysteresisParams(**p, anhysteretic=curve) for p in SETS.values()])
        plain = np.zeros(batch.size)
        extended = np.zeros(batch.size)
        for h0, h1 in zip(field[:-1], field[1:]):
            advance_shared(plain, h0, h1, batch.a, batch.k, batch.alpha, batch.Ms, batch.c, batch.kind, 50.0)
            advance_shared_small_loop(extended, h0, h1, batch.a, batch.k, batch.alpha, batch.Ms, batch.c,
                                      np.zeros(batch.size), batch.kind, 50.0)
        np.testing.assert_array_equal(extended, plain)


def _reference_terms(h, m, delta, p, curve):
    """(irreversible, Man') of (6) written from its formula, not from the kernels (A/m per A/m)."""
    a, k, alpha, Ms, c = p["a"], p["k"], p["alpha"], p["Ms"], p["c"]
    man, man_slope = anhysteretic_magnetization(h + alpha * m, a, Ms, curve)
    gap = float(man) - m
    denominator = k * delta - alpha / (1 - c) * gap
    irreversible = gap / denominator if gap * delta > 0 and denominator * delta > 0 else 0.0
    return irreversible, float(man_slope)


def _small_loop_reference(turning_points, p, chi_r, curve):
    """M at the turning points from an adaptive DOP853 integration of the extension's law,
    written here from its formula (eq. (6) slope + chi_r*(1 - (M/Ms)^2)), not from the kernels."""
    alpha, Ms, c = p["alpha"], p["Ms"], p["c"]

    def slope(h, m, delta, h_rev):
        irreversible, man_slope = _reference_terms(h, m, delta, p, curve)
        return (irreversible + c * man_slope) / (1 - alpha * c * man_slope) + chi_r * max(0.0, 1 - (m / Ms) ** 2)

    return _integrate_legs(turning_points, slope, Ms)


def _integrate_legs(turning_points, slope, Ms):
    """M at the turning points: DOP853 along each monotone leg of ``slope(H, M, delta, H_rev)``, with
    H_rev the leg's starting turning point, from M = 0."""
    m, out = 0.0, [0.0]
    for h0, h1 in zip(turning_points[:-1], turning_points[1:]):
        delta = 1.0 if h1 > h0 else -1.0
        sol = scipy.integrate.solve_ivp(lambda h, y, delta=delta, h0=h0: [slope(h, y[0], delta, h0)], (h0, h1), [m],
                                        method="DOP853", rtol=1e-10, atol=1e-6 * Ms)
        m = float(sol.y[0, -1])
        out.append(m)
    return np.array(out)


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_small_loop_extension_agrees_with_an_independent_adaptive_integration(curve):
    p = SOFT
    chi_r = 3.0
    turning = TURNING_POINTS / 4
    legs = [np.linspace(h0, h1, 41)[:-1] for h0, h1 in zip(turning[:-1], turning[1:])]
    field = np.concatenate(legs + [[turning[-1]]])
    m = simulate_magnetization(field, **p, anhysteretic=curve, chi_r=chi_r, max_field_step=5.0)
    reference = _small_loop_reference(turning, p, chi_r, curve)
    np.testing.assert_allclose(m[::40], reference, atol=2e-6 * p["Ms"])
    # and the extension changed the answer by far more than that tolerance
    plain = simulate_magnetization(field, **p, anhysteretic=curve, max_field_step=5.0)
    assert np.max(np.abs(m - plain)) > 1e-2 * p["Ms"]


def test_small_loop_extension_is_a_reversible_susceptibility_that_fades_at_saturation():
    """Right after a reversal (6) is purely reversible (c*Man', 0 for c = 0), so the extension's
    slope there is chi_r*(1 - (M/Ms)^2): Rayleigh's initial susceptibility, smaller where fewer
    walls are left to bow. Deep in saturation the term vanishes."""
    p = dict(SOFT, c=0.0, alpha=0.0)
    chi_r = 2.0
    for peak in (2e3, 2e4):
        field = np.array([0.0, peak, peak - 5.0])
        m = simulate_magnetization(field, **p, chi_r=chi_r, max_field_step=0.5)
        fading = 1 - ((m[1] + m[2]) / 2 / p["Ms"]) ** 2
        assert (m[1] - m[2]) / 5.0 == pytest.approx(chi_r * fading, rel=1e-6)
        plain = simulate_magnetization(field, **p, max_field_step=0.5)
        assert plain[1] == plain[2]  # (6) alone does not move after this reversal
    big = 2e6 * np.sin(np.linspace(0, 3 * np.pi, 3001))
    top = {value: simulate_magnetization(big, **p, chi_r=value)[1000:].max() for value in (0.0, chi_r)}
    assert top[0.0] < top[chi_r] < p["Ms"]


def test_small_loop_batch_dispatch_and_errors():
    batch = HysteresisBatch.stack([HysteresisParams(**PAPER), HysteresisParams(**PAPER, chi_r=5.0)])
    assert batch.small_loop and not HysteresisBatch.from_params(HysteresisParams(**PAPER), 2).small_loop
    field = np.linspace(0, 2e4, 101)
    both = simulate_batch(field, batch)
    alone = simulate_magnetization(field, **PAPER)
    np.testing.assert_array_equal(both[:, 0], alone)  # a chi_r = 0 member is model (6) exactly
    with pytest.raises(ValueError, match="chi_r must be finite and >= 0"):
        HysteresisParams(chi_r=-1.0)



from hyst_gym.physics.hysteresis import (initial_susceptibility, magnetization_slope,  # noqa: E402
                                         small_loop_magnetization_slope)


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_initial_susceptibility_is_the_reversible_slope_that_vanishing_loops_reach(curve):
    """At the demagnetized state the irreversible term of (6) is off, so the slope is the reversible part with
    its mean-field feedback, c*Man'(0)/(1 - alpha*c*Man'(0)) + chi_r; loops around it of shrinking amplitude
    approach that slope after their reversal. chi_r = 0: the slope of (6), bit for bit."""
    p = dict(a=80.0, k=50.0, alpha=2.5e-4, Ms=2.6e5, c=0.8, anhysteretic=curve)
    kind = HysteresisParams(**p).kind
    for state in ((0.0, 0.0, 1.0), (30.0, 1e5, -1.0), (-5.0, 2e4, 1.0)):
        assert small_loop_magnetization_slope(*state, p["a"], p["k"], p["alpha"], p["Ms"], p["c"], 0.0, kind) == \
            magnetization_slope(*state, p["a"], p["k"], p["alpha"], p["Ms"], p["c"], kind)
    man_slope = p["Ms"] / p["a"] / (1.0 if curve == "ising" else 3.0)
    for chi_r in (0.0, 1400.0):
        expected = p["c"] * man_slope / (1 - p["alpha"] * p["c"] * man_slope) + chi_r
        chi = initial_susceptibility(HysteresisParams(**p, chi_r=chi_r))
        assert chi == pytest.approx(expected, rel=1e-12)
        assert initial_susceptibility(HysteresisParams(**p, chi_r=chi_r, rayleigh_field=10.0)) == chi
        slopes = []
        for peak in (4.0, 1.0, 0.25):  # the slope right after the reversal of a small loop from demagnetized
            field = np.concatenate([np.linspace(0, peak, 50), np.linspace(peak, -peak, 100),
                                    np.linspace(-peak, -0.99 * peak, 5)])
            m = simulate_magnetization(field, **p, chi_r=chi_r, max_field_step=peak / 1000)
            slopes.append((m[-1] - m[-5]) / (field[-1] - field[-5]))
        assert abs(slopes[2] - chi) < abs(slopes[0] - chi)
        assert slopes[2] == pytest.approx(chi, rel=0.01)


# --------------------------------------------------------------- reversal-dependent pinning

from hyst_gym.physics.hysteresis import reversal_weight, simulate_shared, simulate_shared_reversal  # noqa: E402


def test_reversal_kernel_with_zero_rayleigh_field_is_model_6_and_the_small_loop_extension_bit_for_bit():
    """rayleigh_field = 0 weighs the irreversible term by exactly 1: the numbers of (6) (and, with
    chi_r, of the small-loop extension), and the default parameters never reach the new kernel."""
    field = np.concatenate([np.linspace(0, 1.2e5, 300), np.linspace(1.2e5, -3e4, 200), np.linspace(-3e4, 2e4, 50)])
    for curve in ("ising", "langevin"):
        for chi_r in (0.0, 3.0):
            batch = HysteresisBatch.stack([HysteresisParams(**p, anhysteretic=curve, chi_r=chi_r)
                                           for p in SETS.values()])
            zero = np.zeros(batch.size)
            pinned = simulate_shared_reversal(field, zero, batch.a, batch.k, batch.alpha, batch.Ms, batch.c,
                                              batch.chi_r, zero, batch.kind, 50.0)
            np.testing.assert_array_equal(pinned, simulate_batch(field, batch, max_field_step=50.0))
    assert not HysteresisBatch.from_params(HysteresisParams(**PAPER), 3).reversal_pinning
    np.testing.assert_array_equal(simulate_magnetization(field, **PAPER),
                                  simulate_shared(field, np.zeros(1), *(np.array([PAPER[n]]) for n in
                                                  ("a", "k", "alpha", "Ms", "c")), 0, DEFAULT_MAX_FIELD_STEP)[:, 0])


def _reversal_reference(turning_points, p, rayleigh_field, curve):
    """M at the turning points from an adaptive DOP853 integration of REVERSAL_PINNING written
    from its formula (the irreversible term of (6) times 1 - exp(-|H - H_rev|/rayleigh_field),
    H_rev the last turning point), not from the kernels."""
    alpha, Ms, c = p["alpha"], p["Ms"], p["c"]

    def slope(h, m, delta, h_rev):
        irreversible, man_slope = _reference_terms(h, m, delta, p, curve)
        weight = 1 - math.exp(-abs(h - h_rev) / rayleigh_field)
        return (weight * irreversible + c * man_slope) / (1 - alpha * c * man_slope)

    return _integrate_legs(turning_points, slope, Ms)


@pytest.mark.parametrize("curve", ["ising", "langevin"])
def test_reversal_pinning_agrees_with_an_independent_adaptive_integration(curve):
    p = SOFT
    rayleigh_field = 2000.0
    turning = TURNING_POINTS / 4
    legs = [np.linspace(h0, h1, 41)[:-1] for h0, h1 in zip(turning[:-1], turning[1:])]
    field = np.concatenate(legs + [[turning[-1]]])
    m = simulate_magnetization(field, **p, anhysteretic=curve, rayleigh_field=rayleigh_field, max_field_step=5.0)
    np.testing.assert_allclose(m[::40], _reversal_reference(turning, p, rayleigh_field, curve), atol=2e-6 * p["Ms"])
    plain = simulate_magnetization(field, **p, anhysteretic=curve, max_field_step=5.0)
    assert np.max(np.abs(m - plain)) > 5e-3 * p["Ms"]  # far more than the tolerance above


def test_reversal_pinning_grows_like_rayleigh_and_keeps_a_remanent_state_through_small_loops():
    """The onset is Rayleigh's linear growth |dH|/rayleigh_field for small field changes and 1 far
    from the reversal; so a loop much smaller than the pinning field k leaves a remanent state
    where (6) erases a large part of it, while a major loop hardly changes."""
    assert reversal_weight(10.0, 0.0, 1e4) == pytest.approx(1e-3, rel=1e-3)
    assert reversal_weight(-5.0, 5.0, 1.0) == pytest.approx(1.0, abs=1e-4) and reversal_weight(3.0, 0.0, 0.0) == 1.0
    p = dict(SOFT, alpha=0.0)
    remanent = -0.2 * p["Ms"]
    small = 300.0 * np.sin(np.linspace(0, 6 * np.pi, 601))  # three loops of k/5 from the remanent state
    offset = {}
    for rayleigh_field in (0.0, p["k"]):
        m = simulate_magnetization(small, **p, rayleigh_field=rayleigh_field, magnetization0=remanent,
                                   max_field_step=2.0)
        offset[rayleigh_field] = (m[400:].max() + m[400:].min()) / 2
    assert abs(offset[p["k"]] - remanent) < 0.5 * abs(offset[0.0] - remanent)
    major = 2e4 * np.sin(np.linspace(0, 4 * np.pi, 2001))
    loops = [simulate_magnetization(major, **p, rayleigh_field=r)[1000:] for r in (0.0, 0.1 * p["k"])]
    assert np.max(np.abs(loops[1] - loops[0])) < 0.05 * np.ptp(loops[0])


def test_reversal_pinning_errors():
    with pytest.raises(ValueError, match="rayleigh_field must be finite and >= 0"):
        HysteresisParams(rayleigh_field=-1.0)
    with pytest.raises(ValueError, match="rayleigh_field must be finite and >= 0"):
        HysteresisBatch(np.ones(2) * 7012, np.ones(2) * 400, np.zeros(2), np.ones(2) * 7.65e5, np.ones(2) * 0.18,
                        rayleigh_field=np.array([1.0, np.nan]))
