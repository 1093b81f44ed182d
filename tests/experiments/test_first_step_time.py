"""experiments/first_step_time.py: the docs sentence states the three runs, the load, the notice and the verdicts."""

from experiments.first_step_time import markdown


def result(first_s: float, cached_s: float, compiled: bool = True) -> dict:
    first = {"first_step_s": first_s, "episode_steps": 1000, "episode_s": 3.04, "compiled": compiled,
             "compiled_at_s": 17.2, "notice": "hyst-gym: compiling kernels", "load_average_1min": 0.97}
    return {"first_s": first_s, "cached_s": cached_s, "first_notice": "hyst-gym: compiling kernels",
            "cached_notice": "", "load_average_1min": 0.97, "cores": 2, "first": first,
            "cached": {**first, "first_step_s": cached_s, "episode_s": cached_s + 0.04, "notice": ""},
            "foreground": {**first, "first_step_s": 12.36}}


def test_markdown_states_the_three_runs_the_load_and_the_compile_notice():
    text = markdown(result(1.94, 0.66))
    assert "**1.9 s** the first time" in text and "**0.7 s** afterwards" in text
    assert "1-min load up to 1.0" in text and "\"hyst-gym: compiling kernels\"" in text
    assert "first episode (1000 steps) ended 3.0 s after the start (1.10 ms per step, against 0.040 ms " \
           "compiled)" in text
    assert "compiled them 17 s after the start" in text and "the first step takes 12.4 s" in text
    assert "had not finished" in markdown(result(1.94, 0.66, compiled=False))


def test_markdown_says_whether_each_target_is_met():
    from experiments.targets import BY_KEY

    install, cached = BY_KEY["first_step_install"].bound, BY_KEY["first_step_cached"].bound
    fast = markdown(result(install * 0.9, cached * 0.9))
    slow = markdown(result(install * 1.5, cached * 1.5))
    assert f"≤ {install:g} s met the first time, ≤ {cached:g} s met afterwards" in fast
    assert f"≤ {install:g} s not met the first time, ≤ {cached:g} s not met afterwards" in slow
