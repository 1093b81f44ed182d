"""``python -m experiments.suite --suite v1|v2 [options]``: the ``hyst-gym benchmark`` command."""

import argparse
import os
import sys

from experiments.suite.command import configure_parser, main
from hyst_gym.physics.background_compile import FOREGROUND, MODE_VARIABLE

# as `hyst-gym benchmark`: the speed rows time the compiled kernels, so they compile on first use, not in the
# background behind their plain-Python twins
os.environ[MODE_VARIABLE] = FOREGROUND

_parser = argparse.ArgumentParser(prog="python -m experiments.suite", description="the benchmark suites")
configure_parser(_parser)
sys.exit(main(_parser.parse_args()))
