"""``python -m experiments.suite --suite v1|v2 [options]``: the ``hyst-gym benchmark`` command."""

import argparse
import sys

from experiments.suite.command import configure_parser, main

_parser = argparse.ArgumentParser(prog="python -m experiments.suite", description="the benchmark suites")
configure_parser(_parser)
sys.exit(main(_parser.parse_args()))
