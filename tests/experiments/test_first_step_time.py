"""experiments/first_step_time.py: the README sentence states both timings, the load and the notice."""

from experiments.first_step_time import markdown


def test_markdown_states_both_runs_the_load_and_the_compile_notice():
    text = markdown({"first_s": 29.94, "cached_s": 1.06, "first_notice": "numba says\nhyst-gym: compiling kernels",
                     "cached_notice": "", "load_average_1min": 0.97, "cores": 2})
    assert "**29.9 s** the first time" in text and "**1.1 s** afterwards" in text
    assert "1-min load 1.0" in text and "\"hyst-gym: compiling kernels\"" in text



def test_markdown_says_whether_each_target_is_met():
    from experiments.targets import BY_KEY

    install, cached = BY_KEY["first_step_install"].bound, BY_KEY["first_step_cached"].bound
    result = {"first_notice": "", "cached_notice": "", "load_average_1min": 0.1, "cores": 2}
    fast = markdown({**result, "first_s": install * 0.9, "cached_s": cached * 0.9})
    slow = markdown({**result, "first_s": install * 1.5, "cached_s": cached * 1.5})
    assert f"≤ {install:g} s met the first time, ≤ {cached:g} s met afterwards" in fast
    assert f"≤ {install:g} s not met the first time, ≤ {cached:g} s not met afterwards" in slow
