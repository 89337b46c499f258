"""User-facing error type of :mod:`firmware_model`."""

from __future__ import annotations


class UserError(Exception):
    """An error caused by user input (bad config, bad file, bad value). Its message names the file, line or value
    at fault and is printed by the CLI without a traceback."""
