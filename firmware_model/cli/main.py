"""fwemu: a cycle-exact 68000 subset, bit-exact apogee-filter firmware, golden vectors and budgets.

The command-line entry point.

Each subcommand lives in its own module, which exposes ``register(subparsers) -> None`` adding one or more
subparsers whose ``func`` attribute is called with the parsed arguments and returns an exit code. Errors meant
for the user are raised as :class:`firmware_model.runtime.errors.UserError` (or :class:`isa.errors.IsaError`) and
printed as one line without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
from collections.abc import Sequence
from typing import Any

from firmware_model.runtime import output
from firmware_model.runtime.blas_threads import single_threaded_blas
from firmware_model.runtime.errors import UserError
from isa.errors import IsaError

single_threaded_blas()  # before any subcommand imports numpy (firmware_model/runtime/blas_threads.py says why)

#: Every subcommand and the module that registers it, in help order. ``fwemu COMMAND ...`` imports only that
#: command's module (a command's domain modules and their dependencies, e.g. hypothesis for check-port, cost up
#: to 0.3 s to import: every run would pay for all of them); ``fwemu``, ``fwemu --help`` and an unknown command
#: import them all. tests/cli/test_structure.py checks this table against what the modules register.
COMMANDS: dict[str, str] = {
    "asm": "isa.cli",
    "exec": "isa.cli",
    "design": "firmware_model.cli.design",
    "compare": "firmware_model.cli.compare",
    "budget": "firmware_model.cli.budget",
    "inputs": "firmware_model.cli.inputs",
    "vectors": "firmware_model.cli.vectors",
    "simulate": "firmware_model.cli.simulate",
    "run": "firmware_model.cli.run",
    "plot": "firmware_model.cli.plot",
    "evaluate": "firmware_model.cli.evaluate",
    "sweep": "firmware_model.cli.sweep",
    "check-port": "firmware_model.cli.check_port",
    "reconstruct": "firmware_model.cli.reconstruct",
    "montecarlo": "firmware_model.cli.montecarlo",
}

#: Modules that contribute subcommands, in help order.
COMMAND_MODULES: tuple[str, ...] = tuple(dict.fromkeys(COMMANDS.values()))


_ROLE = re.compile(r":[a-z]+:`~?(?:[\w.]*\.)?([^`<>]+?)`")
_LITERAL = re.compile(r"``([^`]+)``")


def plain(text: str | None) -> str | None:
    """Help text without reST markup: ``x`` -> x, :func:`~a.b.f` -> f (docstrings double as --help)."""
    if not text:
        return text
    return _LITERAL.sub(r"\1", _ROLE.sub(r"\1", text))


def _clean_help(parser: argparse.ArgumentParser) -> None:
    parser.description = plain(parser.description)
    parser.epilog = plain(parser.epilog)
    for action in parser._actions:
        action.help = plain(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                choice.help = plain(choice.help)
            for sub in dict.fromkeys(action.choices.values()):
                _clean_help(sub)


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """Build the ``fwemu`` argument parser: from the module of the command ``argv`` names (its first word that is
    not an option), or from every module in :data:`COMMAND_MODULES` when it names none or an unknown one."""
    parser = argparse.ArgumentParser(prog="fwemu", description=__doc__.splitlines()[0] if __doc__ else None)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    first = next((a for a in argv or () if not a.startswith("-")), None)
    for name in ((COMMANDS[first],) if first in COMMANDS else COMMAND_MODULES):
        module = importlib.import_module(name)  # lazy by design: only the command that runs (table above)
        module.register(subparsers)
    _clean_help(parser)
    return parser


class _StdoutError(OSError):
    """Writing standard output failed (full disk, ``> /dev/full``, I/O error)."""


class _GuardedStdout:
    """A proxy of ``sys.stdout`` whose write/flush failures are :class:`_StdoutError` (told apart from the
    failures of output files, which carry a file name)."""

    def __init__(self, stream: object) -> None:
        self._stream = stream
        #: the first write failure, kept because argparse's ``--help`` swallows the OSError of its own write
        self.failure: _StdoutError | None = None

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)  # type: ignore[attr-defined]  # the wrapped stream is typed as object
        except BrokenPipeError:
            raise
        except OSError as exc:
            err = _StdoutError(exc.errno, exc.strerror or str(exc))
            self.failure = self.failure or err
            raise err from None

    def flush(self) -> None:
        try:
            self._stream.flush()  # type: ignore[attr-defined]  # the wrapped stream is typed as object
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise _StdoutError(exc.errno, exc.strerror or str(exc)) from None

    def __getattr__(self, name: str) -> object:
        return getattr(self._stream, name)


def _silence_stdout() -> None:
    """Point the stdout file descriptor at /dev/null so the interpreter's final flush cannot fail again."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        return
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
    except OSError:
        pass


def _say(line: str) -> None:
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _os_error_line(exc: OSError) -> str:
    """One line for an OSError the user can act on (read-only, not a folder, disk full, no permission)."""
    why = exc.strerror or str(exc)
    if exc.filename is not None:
        return f"fwemu: error: {exc.filename}: {why}"
    return f"fwemu: error: {why}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``fwemu`` with ``argv`` (default: ``sys.argv[1:]``) and return the process exit code.

    Exit codes: 0 success, 1 a check failed (e.g. ``vectors --check``), 2 a user error (bad input, bad value,
    an output that cannot be written, a full standard output; one line on stderr, never a traceback),
    130/143 interrupted by SIGINT/SIGTERM (one line; previous outputs left intact, no temporary files)."""

    output.reset_run_state()
    real_stdout = sys.stdout
    sys.stdout = _GuardedStdout(real_stdout)  # type: ignore[assignment]  # a proxy of sys.stdout, not a TextIO subclass
    try:
        with output.interruptible():
            _declare_out_early(sys.argv[1:] if argv is None else argv, output)
            return _run(argv, output, (UserError, IsaError))
    finally:
        sys.stdout = real_stdout


def _declare_out_early(argv: Sequence[str], output: Any) -> None:
    """Name ``--out``'s value as soon as the signal handlers are in place, before the parser is built and the
    command's modules are imported (which can take a second on a loaded machine): an interrupt at any moment of
    the run then says which outputs were left intact, not "nothing written". The command declares it again
    (harmless) once parsed; a value the parser later refuses was never written to, so the line stays true."""
    for i, arg in enumerate(argv):
        if arg == "--":
            break
        if arg == "--out" and i + 1 < len(argv):
            output.declare_output(argv[i + 1])
        elif arg.startswith("--out="):
            output.declare_output(arg[len("--out="):])


def _run(argv: Sequence[str] | None, output: Any, user_errors: tuple[type[BaseException], ...]) -> int:
    try:
        try:
            parser = build_parser(sys.argv[1:] if argv is None else argv)
            args = parser.parse_args(argv)
            code = int(args.func(args) or 0)
            output.raise_if_interrupted()  # a signal whose exception a finalizer swallowed still ends the run
        except SystemExit:  # argparse: --help, usage errors (exit 2); kept as SystemExit for callers of main()
            sys.stdout.flush()
            failure = getattr(sys.stdout, "failure", None)
            if failure is not None:       # `fwemu --help > /dev/full`: argparse swallowed the write error
                raise failure from None
            raise
        sys.stdout.flush()  # a full stdout (`> /dev/full`) fails here at the latest
        return code
    except user_errors as exc:
        _say(f"fwemu: error: {exc}")
        return 2
    except BrokenPipeError:  # `fwemu ... | head`: the reader is gone; not an error
        _silence_stdout()
        return 0
    except _StdoutError as exc:
        _silence_stdout()
        _say(f"fwemu: error: cannot write to standard output: {exc.strerror}")
        return 2
    except output.Interrupted as exc:
        _say(output.interrupted_message(exc))
        return int(exc.exit_code)
    except KeyboardInterrupt:
        _say(output.interrupted_message())
        return 130
    except OSError as exc:
        _say(_os_error_line(exc))
        return 2
    except Exception:
        # A signal that lands inside a library (e.g. numba compiling a kernel) can surface as some other error
        # (numba: "RuntimeError: no compiled object yet"): after a signal, any failure is the interruption.
        pending = output.pending_signal()
        if pending is None:
            raise
        _say(output.interrupted_message())
        return 128 + pending


def entry() -> None:
    """The ``fwemu`` console script: :func:`main`, then exit with its code. Once main has returned the outputs are
    settled, so SIGINT/SIGTERM are ignored from then on (a Ctrl-C during interpreter shutdown would otherwise raise
    inside library finalizers). After an interrupt, errors that library finalizers raise at shutdown are not
    printed: the one line has said what happened, and numba/llvmlite objects half-built when the signal landed
    print "Exception ignored ... AttributeError" tracebacks from their ``__del__`` (seen in a fresh clone's CI)."""
    import signal

    code = main()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    if code in (130, 143):
        sys.unraisablehook = lambda unraisable: None
    sys.exit(code)


if __name__ == "__main__":
    entry()
