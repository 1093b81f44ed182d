"""The ``hyst-gym`` command.

Each subcommand lives in the module of the layer that owns it; that module provides
``configure_parser(parser)`` and ``main(args) -> int``. Modules are imported only when
their subcommand runs, so ``hyst-gym --help`` stays fast.

Bad input (a malformed recording, a parameter out of range, a missing file) ends with
one line on stderr and exit status 2, never a traceback; set ``HYST_GYM_DEBUG=1`` to
see the traceback anyway.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

#: subcommand -> (module, one-line help)
SUBCOMMANDS = {
    "demo": ("experiments.demo", "run the end-to-end demo (paper example, baselines, PPO, figures)"),
    "bench": ("hyst_gym.bench", "measure kernel, estimator and environment speed"),
    "reproduce": ("experiments.reproduce_paper", "reproduce the paper's numerical examples (Figs. 8-11)"),
    "train": ("baselines.train", "train a PPO, SAC or RecurrentPPO excitation policy"),
    "evaluate": ("baselines.evaluate", "evaluate an agent, write per-episode CSV"),
    "diagnose": ("hyst_gym.diagnose.command", "find which physics a recording shows that the model lacks"),
    "make-recording": ("hyst_gym.diagnose.make_recording", "write a synthetic recording with a concealed effect"),
}

#: top-level modules of the optional ``rl`` extra
OPTIONAL_RL_MODULES = ("stable_baselines3", "sb3_contrib", "torch")


def _top_module(error: ModuleNotFoundError) -> str:
    return (error.name or "").split(".")[0]


def build_parser(selected: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hyst-gym", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        command_parser = sub.add_parser(name, help=help_text, description=help_text)
        if name == selected:
            _load(module_name).configure_parser(command_parser)
    return parser


def _load(module_name: str):
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name and module_name.startswith(error.name):
            raise SystemExit(f"hyst-gym: this subcommand is not available ({module_name} is missing)")
        if _top_module(error) in OPTIONAL_RL_MODULES and not os.environ.get("HYST_GYM_DEBUG"):
            raise SystemExit(f"hyst-gym: this subcommand needs {_top_module(error)}; install the RL extra: "
                             "pip install 'hyst-gym[rl]'")
        raise


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    selected = next((a for a in argv if a in SUBCOMMANDS), None)
    parser = build_parser(selected)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    module = _load(SUBCOMMANDS[args.command][0])
    try:
        return int(module.main(args) or 0)
    except ModuleNotFoundError as error:
        if _top_module(error) not in OPTIONAL_RL_MODULES or os.environ.get("HYST_GYM_DEBUG"):
            raise
        print(f"hyst-gym {args.command}: error: needs {_top_module(error)}; install the RL extra: "
              "pip install 'hyst-gym[rl]'", file=sys.stderr)
        return 2
    except (ValueError, OSError, KeyError) as error:
        if os.environ.get("HYST_GYM_DEBUG"):
            raise
        message = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        print(f"hyst-gym {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"hyst-gym {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
