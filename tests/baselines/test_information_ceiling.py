"""The Van Trees ceiling of suite v2 against the Fisher information that baselines.information computes
independently (a test of the estimation layer's bound that needs the checkout's baselines, so it lives
here: the estimation layer's own tests run from an installed wheel)."""

import numpy as np

from hyst_gym.estimation.information_bound import information_ceiling, random_admissible_fields


def test_ceiling_holds_for_admissible_inputs_computed_independently():
    """The Fisher information of the first-order plant under several admissible inputs, computed by
    baselines.information (finite difference and the plant filter), stays below the ceiling."""
    from baselines.information import fisher_information
    from hyst_gym.envs.suite_v2 import bound_setting, task_config_v2
    from hyst_gym.estimation.information_bound import sensitivity_table

    config = task_config_v2("hyst_gym/HotCalibrate-v0")
    setting = bound_setting(config)
    table = sensitivity_table(config.hysteresis, (setting.a_lo, 7900.0), config.field_limit, config.max_field_change,
                              config.max_field_step, n_paths=32, steps=config.episode_steps)
    ceiling = information_ceiling(setting, table)
    scale = config.transducer.gain * config.hysteresis.Ms / config.transducer.decay_rate
    ramp = np.minimum(config.max_field_change * np.arange(1, 201), 8.1e4)
    inputs = [ramp] + list(random_admissible_fields(6, 200, config.max_field_change, 1e5, seed=7).T)
    for field in inputs:
        for a in (6700.0, 7300.0):
            info = fisher_information(field, config.dt, [a], config.hysteresis.replace(a=a), config.transducer,
                                      noise_std=setting.sigma * scale)[0]
            assert info <= ceiling[-1]
    # the slew ramp to the peak field comes within a factor 2 of the ceiling (the relaxation is not vacuous)
    best = fisher_information(ramp, config.dt, [7012.0], config.hysteresis, config.transducer,
                              noise_std=setting.sigma * scale)[0]
    assert best > 0.5 * ceiling[-1]
