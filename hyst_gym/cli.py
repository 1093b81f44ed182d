"""The ``hyst-gym`` command.

Each subcommand lives in the module of the layer that owns it; that module provides
``configure_parser(parser)`` and ``main(args) -> int``. Modules are imported only when
their subcommand runs (or shows its help), and they import nothing heavy (PyTorch,
Stable-Baselines3) at module level, so ``hyst-gym --help`` and ``hyst-gym COMMAND
--help`` stay fast and work without the ``rl`` extra.

Five subcommands (``demo``, ``reproduce``, ``train``, ``evaluate``, ``benchmark``) live in the
benchmark's ``baselines/`` and ``experiments/`` packages, which only a clone of the
repository has (the wheel installs ``hyst_gym`` alone). They are imported from the
checkout that ``hyst_gym`` itself was imported from, never from a same-named package
elsewhere on ``sys.path`` (a user's own ``experiments/``).

Bad input (a malformed recording, a parameter out of range, a missing file) ends with
one line on stderr and exit status 2, never a traceback; set ``HYST_GYM_DEBUG=1`` to
see the traceback anyway.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import hyst_gym
from hyst_gym.physics.background_compile import FOREGROUND, MODE_VARIABLE

DESCRIPTION = ("hyst-gym: hysteretic magnetostrictive transducers (Terfenol-D) as a benchmark for adaptive "
               "estimation and reinforcement learning.")


@dataclass(frozen=True)
class Subcommand:
    module: str
    help: str
    #: lives in baselines/ or experiments/, which only a clone of the repository has
    checkout_only: bool = False
    #: times the compiled kernels, so they compile on first use (``HYST_GYM_COMPILE=foreground``) instead of in
    #: the background while their plain-Python twins step, which the timings would then measure
    times_kernels: bool = False


SUBCOMMANDS = {
    "demo": Subcommand("experiments.demo", "run the end-to-end demo (paper example, baselines, PPO, figures)", True),
    "bench": Subcommand("hyst_gym.layer_speed", "measure kernel, estimator and environment speed", times_kernels=True),
    "reproduce": Subcommand("experiments.reproduce_paper", "reproduce the paper's numerical examples (Figs. 8-11)",
                            True),
    "train": Subcommand("baselines.train", "train a PPO, SAC or RecurrentPPO excitation policy", True),
    "evaluate": Subcommand("baselines.evaluate", "evaluate an agent, write per-episode CSV", True),
    "benchmark": Subcommand("experiments.suite.command",
                            "run the benchmark suite (--suite v1 or v2): floors, baselines, RL, table, figure", True,
                            times_kernels=True),
    "diagnose": Subcommand("hyst_gym.diagnose.command", "find which physics a recording shows that the model lacks"),
    "make-recording": Subcommand("hyst_gym.diagnose.make_recording",
                                 "write a synthetic recording with a concealed effect"),
}

#: top-level modules of the optional ``rl`` extra (pyproject.toml)
RL_EXTRA_MODULES = ("stable_baselines3", "sb3_contrib", "torch", "tensorboard", "cma")
RL_EXTRA_INSTALL = "pip install 'hyst-gym[rl]'"

#: the packages of the benchmark that only a clone of the repository has
CHECKOUT_PACKAGES = ("baselines", "experiments")
REPOSITORY_URL = "https://github.com/hyst-gym/hyst-gym"
CLONE_NOTE = ("this command runs from a clone of the repository (it needs the benchmark's baselines/ and "
              "experiments/ packages, which the wheel does not install): "
              f"git clone {REPOSITORY_URL} && cd hyst-gym && bash scripts/setup.sh")


class CommandError(Exception):
    """Bad input or a missing piece, reported as one line and exit status 2."""


def repository_root() -> Path:
    """The folder holding the ``hyst_gym`` package that is running (a clone's root)."""
    return Path(hyst_gym.__file__).resolve().parents[1]


def _has_checkout(root: Path) -> bool:
    """Whether ``root`` is a clone: its pyproject.toml tells it from a site-packages folder
    that happens to hold packages of these names (OpenAI's ``baselines`` is one)."""
    return (root / "pyproject.toml").is_file() and all((root / package / "__init__.py").is_file()
                                                       for package in CHECKOUT_PACKAGES)


def _use_checkout_packages() -> None:
    """Make ``baselines`` and ``experiments`` resolve to this checkout's packages.

    The checkout's root goes to the front of ``sys.path``, so that neither the working
    directory nor ``PYTHONPATH`` can put another package of the same name first; a
    package already imported from elsewhere cannot be replaced, so it is an error."""
    root = repository_root()
    if not _has_checkout(root):
        raise CommandError(CLONE_NOTE)
    if not sys.path or sys.path[0] != str(root):
        sys.path.insert(0, str(root))
    for package in CHECKOUT_PACKAGES:
        module = importlib.import_module(package)
        # a namespace package (a folder without __init__.py) has no __file__
        location = Path(getattr(module, "__file__", None) or next(iter(getattr(module, "__path__", [])), "?"))
        if not location.resolve().is_relative_to(root):
            raise CommandError(f"the '{package}' package was imported from {location}, not from this checkout "
                               f"({root / package}); rename that package or take it off sys.path")


def _top_module(error: ModuleNotFoundError) -> str:
    return (error.name or "").split(".")[0]


def _needs_rl_extra(missing: list[str]) -> CommandError:
    return CommandError(f"needs {', '.join(missing)}; install the RL extra: {RL_EXTRA_INSTALL}")


def _load(name: str):
    """The module of subcommand ``name``; raises :class:`CommandError` if it cannot run here."""
    subcommand = SUBCOMMANDS[name]
    if subcommand.checkout_only:
        _use_checkout_packages()
    try:
        return importlib.import_module(subcommand.module)
    except ModuleNotFoundError as error:
        if _top_module(error) in RL_EXTRA_MODULES and not os.environ.get("HYST_GYM_DEBUG"):
            raise _needs_rl_extra([_top_module(error)]) from None
        raise


def rl_modules_needed(args) -> tuple[str, ...]:
    """The modules of the rl extra that ``args.command`` will import. They are looked for
    before the command starts, so that a missing one does not end a long run half way."""
    if args.command == "train":
        recurrent = ("sb3_contrib",) if args.algo == "recurrent_ppo" else ()
        return ("torch", "stable_baselines3", "tensorboard") + recurrent
    if args.command == "benchmark":
        return ("torch", "stable_baselines3", "tensorboard", "cma")  # RL models and the CMA-ES designs
    if args.command == "demo" and not args.physics_only:
        return ("torch", "stable_baselines3", "tensorboard", "cma")  # PPO and the CMA-ES design
    return ()


def _missing(modules) -> list[str]:
    """The top-level modules of ``modules`` that cannot be imported (without importing them)."""
    def importable(name):
        try:
            return importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a broken or blocked install counts as missing
            return False

    return [name for name in modules if not importable(name)]


def _selected(argv: list[str]) -> str | None:
    """The subcommand named by ``argv`` (the first argument that is not an option)."""
    first = next((arg for arg in argv if not arg.startswith("-")), None)
    return first if first in SUBCOMMANDS else None


class OneLineErrorParser(argparse.ArgumentParser):
    """argparse, with a usage error on one line (no usage block), like every other error
    of the command; ``--help`` shows the usage."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser(selected: str | None = None, module=None) -> argparse.ArgumentParser:
    """The parser; the subparser of ``selected`` is configured by ``module`` (its module),
    or, with no module, carries only its description (``--help`` of a checkout-only
    command outside a clone)."""
    parser = OneLineErrorParser(prog="hyst-gym", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"hyst-gym {hyst_gym.__version__}",
                        help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    for name, subcommand in SUBCOMMANDS.items():
        command_parser = sub.add_parser(name, help=subcommand.help, description=subcommand.help)
        if name != selected:
            continue
        if module is not None:
            module.configure_parser(command_parser)
        else:
            command_parser.epilog = CLONE_NOTE
    return parser


def _run(argv: list[str]) -> int:
    selected = _selected(argv)
    module = None
    if selected is not None:
        help_only = "-h" in argv or "--help" in argv
        if not (help_only and SUBCOMMANDS[selected].checkout_only and not _has_checkout(repository_root())):
            module = _load(selected)
        # else: outside a clone the help still shows, saying how to get a clone; running does not
    parser = build_parser(selected, module)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    missing = _missing(rl_modules_needed(args))
    if missing:
        raise _needs_rl_extra(missing)
    if SUBCOMMANDS[args.command].times_kernels:
        os.environ[MODE_VARIABLE] = FOREGROUND  # this process's own setting, inherited by its workers
    try:
        return int(module.main(args) or 0)
    except ModuleNotFoundError as error:
        if _top_module(error) not in RL_EXTRA_MODULES or os.environ.get("HYST_GYM_DEBUG"):
            raise
        raise _needs_rl_extra([_top_module(error)]) from None
    except (ValueError, OSError, KeyError) as error:
        if os.environ.get("HYST_GYM_DEBUG"):
            raise
        text = str(error).strip()
        raise CommandError(text.splitlines()[0] if text else type(error).__name__) from None


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        return _run(argv)
    except CommandError as error:
        print(f"{_prog(argv)}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{_prog(argv)}: interrupted", file=sys.stderr)
        return 130


def _prog(argv: list[str]) -> str:
    """``hyst-gym`` or ``hyst-gym COMMAND``, as argparse starts its error lines."""
    command = _selected(argv)
    return f"hyst-gym {command}" if command else "hyst-gym"


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
