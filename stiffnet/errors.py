"""User-facing errors.

Every problem caused by the user's input (bad configuration, malformed recording,
signal unusable for an estimate) raises :class:`StiffnetError` with a one-line
message that names the problem. The CLI turns it into ``error: ...`` and exit
code 2; the HTTP predictor into a 4xx JSON body. Anything else is a bug.
"""

from __future__ import annotations


class StiffnetError(ValueError):
    """Invalid input, with a one-line message meant for the user."""


class ConfigError(StiffnetError):
    """A configuration value is missing, unknown or out of range."""


class SignalError(StiffnetError):
    """A signal cannot be analysed (NaN/inf, constant, too short, no impacts...)."""


class RateMismatch(StiffnetError):
    """A recording's own rate (its time column, header or channel property) disagrees with
    the one given: the caller that gave it (a manifest row) adds where it came from."""


class EnvironmentFailure(StiffnetError):
    """The environment failed, not the input (disk full, a server unreachable): exit 1."""

    exit_code = 1
