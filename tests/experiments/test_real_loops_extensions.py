"""experiments/real_loops_extensions.py: the Rayleigh-type extensions tried against the ferrite's 8 A/m miss."""

import json

import numpy as np
import pytest
from scipy.special import erf

from experiments import real_loops, real_loops_extensions as ext
from hyst_gym.physics.hysteresis import simulate_magnetization

MU0 = 4e-7 * np.pi


def test_page_section_is_the_committed_study():
    """The real-loops-extensions section of docs/results/real-loops.md is what the script writes from the committed
    JSON (rerun: python -m experiments.real_loops_extensions)."""
    from tests.test_docs_sections import section

    payload = json.loads(ext.JSON.read_text())
    assert section(real_loops.PAGE, ext.AREA) == ext.page_section(payload).strip()


def test_reversal_permeability_of_a_rayleigh_loop():
    """On Rayleigh's loop (B/mu0 = (mu_i + eta*Hm)*H -+ eta/2*(Hm^2 - H^2)) the slope right after the reversal
    starts at mu_i and grows as eta*|H - H_rev|: the least-squares slope over the first 10 % of the range
    (0.2*Hm), on samples uniform in H, is mu_i + 0.1*eta*Hm."""
    mu_i, eta, peak = 5000.0, 200.0, 8.0
    H = peak * (2 * np.abs(2 * np.arange(1024) / 1024 - 1) - 1)  # a triangle: down from +Hm, then up
    descending = np.arange(H.size) < H.size // 2
    b = (mu_i + eta * peak) * H + np.where(descending, 1, -1) * 0.5 * eta * (peak ** 2 - H ** 2)
    assert ext.reversal_permeability(H, MU0 * b) == pytest.approx(mu_i + 0.1 * eta * peak, rel=2e-3)


def test_reversal_pinning_with_a_vanishing_rayleigh_field_is_the_small_loop_model():
    """rayleigh_field -> 0 weighs the irreversible term by 1: the small-loop extension of (6) itself."""
    a, k, alpha, Ms, c, chi_r = 70.0, 50.0, 2.5e-4, 2.6e5, 0.8, 1400.0
    rho = alpha * Ms / a
    z = np.array([np.log(a), np.log(k), np.log(rho / (1 - rho)), np.log(Ms), np.log(c / (1 - c)), np.log(chi_r),
                  np.log(1e-9)])
    field = 80.0 * np.sin(np.linspace(0, 4 * np.pi, 400))
    pinned = ext.wall_magnetization(field, z, 0.08)[:, 0]
    plain = simulate_magnetization(np.concatenate([[0.0], field]), a=a, k=k, alpha=alpha, Ms=Ms, c=c, chi_r=chi_r,
                                   anhysteretic="ising", max_field_step=0.08)[1:]
    np.testing.assert_allclose(pinned, plain, atol=1e-9 * Ms)


def test_uniform_low_coercivity_relays_approach_the_anhysteretic_population_as_their_width_vanishes():
    """Relays of coercivity -> 0 have no hysteresis: their column is the anhysteretic share erf(H/(sqrt(2) b))."""
    names = ext._hem_names()
    values = dict(coercive_median=7.0, coercive_spread=0.9, interaction_scale=4.0, reversible_saturation=50.0,
                  anhysteretic_scale=10.0, uniform_width=1e-6)
    field = 40.0 * np.sin(np.linspace(0, 4 * np.pi, 300))
    uniform = ext.hem_columns(field, np.array([[values[n] for n in names]]))[-1][:, 0]
    np.testing.assert_allclose(uniform, erf(field / (np.sqrt(2) * 4.0)), atol=1e-6)
