"""experiments/real_loops.py --model: the HEM fitter and the selection rule."""

import numpy as np
import pytest

from experiments import real_loops
from hyst_gym.physics.hem import HEMBatch, HEMParams, simulate_hem_batch

MU0 = 4e-7 * np.pi
TRUE = HEMParams(relay_magnetization=2.5e5, reversible_susceptibility=300.0, coercive_median=6.0,
                 coercive_spread=0.5, interaction_scale=12.0, coercive_nodes=16)


def synthetic_loops(params, peaks=(80.0, 30.0, 10.0), samples=129):
    """Closed loops (H, B) of a known HEM, each a steady cycle as the measured loops are."""
    loops = []
    for peak in peaks:
        H = peak * np.cos(np.linspace(0, 2 * np.pi, samples))
        played = np.concatenate([[0.0], H, H])
        M = simulate_hem_batch(played, HEMBatch.from_params(params))[1:, 0][samples:]
        loops.append((H, MU0 * (H + M)))
    return loops


def test_hem_fit_recovers_a_known_model_and_predicts_its_small_loops():
    loops = synthetic_loops(TRUE)
    rec = real_loops.loop_recording([loops[0]], "synthetic")
    mask = np.zeros(rec.size, bool)
    mask[loops[0][0].size:] = True
    fit = real_loops.fit_hem(rec, "normal", mask)
    for name in ("relay_magnetization", "reversible_susceptibility", "coercive_median", "interaction_scale"):
        assert getattr(fit.params, name) == pytest.approx(getattr(TRUE, name), rel=0.05), name
    for H, B in loops[1:]:
        other, m = real_loops.predict_loop(fit, H, B, "small")
        assert real_loops.nrmse_of_b(other, m, H.size, 2 * H.size) < 0.01


def _row(variant, segment, *nrmse):
    return {"variant": variant, "selection_segment_rmse_A_per_m": segment,
            "nrmse_B": {f"{80 / (i + 1):.3g} A/m": v for i, v in enumerate(nrmse)}}


def test_rule_takes_the_best_transfer_among_candidates_that_fit_the_held_out_segment():
    rows = [_row("a", 100.0, 0.01, 0.2), _row("b", 140.0, 0.01, 0.3), _row("c", 400.0, 0.01, 0.4)]
    transfer = {"a": 0.10, "b": 0.05, "c": 0.01}
    # c transfers best but misses the target's own held-out segment (4x the best): not admissible
    assert real_loops.choose_variant(rows, transfer)["variant"] == "b"
    # without transfer scores the segment decides
    assert real_loops.choose_variant(rows, {})["variant"] == "a"


def test_transfer_score_leaves_the_target_material_out():
    shared = {"x": [_row("a", 1.0, 0.01, 0.02, 0.30)], "y": [_row("a", 1.0, 0.01, 0.10, 0.04)]}
    assert real_loops.transfer_scores(shared) == {"a": pytest.approx((0.30 + 0.10) / 2)}
    assert real_loops.transfer_scores(shared, exclude={"x"}) == {"a": pytest.approx(0.10)}
    loops = synthetic_loops(TRUE, peaks=(50.0,))
    assert real_loops.held_out_materials(loops, {"x": ([], loops), "y": ([], synthetic_loops(TRUE, (40.0,)))}) == {"x"}


def test_saturating_hem_fit_recovers_the_reversible_saturation():
    true = TRUE.replace(reversible_saturation=30.0, reversible_susceptibility=2000.0)
    loops = synthetic_loops(true)
    rec = real_loops.loop_recording([loops[0]], "synthetic")
    mask = np.zeros(rec.size, bool)
    mask[loops[0][0].size:] = True
    fit = real_loops.fit_hem(rec, "normal", mask, saturating=True)
    assert fit.params.reversible_saturation == pytest.approx(30.0, rel=0.05)
    assert fit.params.reversible_susceptibility == pytest.approx(2000.0, rel=0.05)
    # the linear-reversible HEM cannot follow the bounded reversible part as closely
    linear = real_loops.fit_hem(rec, "normal", mask)
    assert fit.sse < 0.1 * linear.sse
