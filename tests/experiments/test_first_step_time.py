"""experiments/first_step_time.py: the README sentence states both timings, the load and the notice."""

from experiments.first_step_time import markdown


def test_markdown_states_both_runs_the_load_and_the_compile_notice():
    text = markdown({"first_s": 29.94, "cached_s": 1.06, "first_notice": "numba says\nhyst-gym: compiling kernels",
                     "cached_notice": "", "load_average_1min": 0.97, "cores": 2})
    assert "**29.9 s** the first time" in text and "**1.1 s** afterwards" in text
    assert "1-min load 1.0" in text and "\"hyst-gym: compiling kernels\"" in text

