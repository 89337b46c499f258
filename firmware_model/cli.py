"""fwemu: a cycle-exact 68000 subset, bit-exact apogee-filter firmware, golden vectors and budgets.

The command-line entry point.

Each subcommand lives in its own module, which exposes ``register(subparsers) -> None`` adding one or more
subparsers whose ``func`` attribute is called with the parsed arguments and returns an exit code. Errors meant
for the user are raised as :class:`firmware_model.errors.UserError` (or :class:`isa.errors.IsaError`) and
printed as one line without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

#: Modules that contribute subcommands, in help order.
COMMAND_MODULES: tuple[str, ...] = (
    "isa.cli",
    "firmware_model.cli_design",
    "firmware_model.cli_compare",
    "firmware_model.cli_budget",
    "firmware_model.cli_vectors",
)


def build_parser() -> argparse.ArgumentParser:
    """Build the ``fwemu`` argument parser from every module in :data:`COMMAND_MODULES`."""
    parser = argparse.ArgumentParser(prog="fwemu", description=__doc__.splitlines()[0] if __doc__ else None)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    for name in COMMAND_MODULES:
        module = importlib.import_module(name)
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``fwemu`` with ``argv`` (default: ``sys.argv[1:]``) and return the process exit code."""
    from firmware_model.errors import UserError  # local: keep start-up light
    from isa.errors import IsaError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (UserError, IsaError) as exc:
        print(f"fwemu: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
