"""The ``mna`` command line: one place that wires the stages together.

Each subcommand lives in ``mna/commands/<group>.py`` with a ``register(subparsers)``
function that adds its parsers and sets ``func`` to a handler ``func(args) -> int``.

Exit codes and errors (never a traceback unless ``MNA_DEBUG=1``):

* 0: done.
* 2: bad input, an impossible request or the environment (``MnaError``, ``ValueError``,
  ``TypeError``, ``OSError``, out of memory): one line ``mna CMD: error: ...`` on stderr.
* 1: anything else is a bug in mna: one line naming the exception, and one asking for a report.
* 130 / 143: stopped by Ctrl-C (SIGINT) / SIGTERM; a fit saves its checkpoint first.
"""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

import mna  # noqa: F401  (sets OMP_WAIT_POLICY before anything imports torch)
from mna.interrupt import Terminated, exit_code, on_sigterm_raise

COMMAND_MODULES = (
    "mna.commands.fit",
    "mna.commands.texture",
    "mna.commands.unwrap",
    "mna.commands.render",
    "mna.commands.train",
    "mna.commands.demo",
)

EXIT_BUG = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = exit_code(signal.SIGINT)
EXIT_TERMINATED = exit_code(signal.SIGTERM)
BUG_LINE = "mna: this is a bug, please report it (MNA_DEBUG=1 shows the traceback)"

#: exceptions that mean bad input or environment, not a bug in mna
INPUT_ERRORS = (ValueError, TypeError, OSError, MemoryError)
#: path arguments that must not be empty (``-o ""`` would silently mean the current folder)
PATH_ARGS = {"out": "-o/--out", "run": "RUN", "runs": "RUN", "input": "INPUT", "mesh": "MESH",
             "checkpoint": "CHECKPOINT", "config": "the config path", "reference": "--reference", "root": "--root"}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse's own errors: one line, exit 2
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="mna", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def _check_paths(args: argparse.Namespace) -> None:
    for name, label in PATH_ARGS.items():
        value = getattr(args, name, None)
        values = value if isinstance(value, list) else [value]
        if any(isinstance(v, str) and not v.strip() for v in values):
            from mnacore.errors import MnaError

            raise MnaError(f"{label} must not be empty")


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else ""


def is_input_error(exc: BaseException) -> bool:
    """Bad input or environment (exit 2) rather than a bug (exit 1)."""
    # torch.OutOfMemoryError is a RuntimeError; matched by name so the CLI needs no torch
    return isinstance(exc, INPUT_ERRORS) or type(exc).__name__ == "OutOfMemoryError"


def run_command(prog: str, func, args) -> int:
    """Call ``func(args)`` and turn every exception into the exit codes of the module doc."""
    try:
        return int(func(args) or 0)
    except Terminated:
        print(f"{prog}: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:
        if os.environ.get("MNA_DEBUG"):
            raise
        if is_input_error(exc):
            print(f"{prog}: error: {_first_line(exc) or type(exc).__name__}", file=sys.stderr)
            return EXIT_USAGE
        detail = _first_line(exc)
        print(f"{prog}: internal error: {type(exc).__name__}" + (f": {detail}" if detail else ""), file=sys.stderr)
        print(BUG_LINE, file=sys.stderr)
        return EXIT_BUG


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = None
    try:
        previous = signal.signal(signal.SIGTERM, on_sigterm_raise)
    except ValueError:  # not the main thread (mna.cli.main called from a worker)
        previous = None

    def command(a):
        _check_paths(a)
        return a.func(a)

    try:
        return run_command(f"mna {args.command}", command, args)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
