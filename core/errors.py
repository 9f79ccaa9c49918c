"""Exceptions the core raises for bad input; messages name the file, field or parameter."""
from __future__ import annotations


class PushbroomError(Exception):
    """Base class: a problem the user can fix, described in plain words."""


class MetadataError(PushbroomError):
    """A metadata or scene file is unreadable, truncated or lacks a required field."""


class InputError(PushbroomError):
    """A parameter or data value is outside what the algorithm accepts (NaN, CRS, coverage...).

    ``parameter``: the input the error concerns, in the core's own terms ('gcps', 'ties',
    'lines', 'scene', 'settings.<field>' of :class:`core.adjust.settings.AdjustmentSettings`),
    for the caller to name its own parameter; '' when it concerns several inputs, which the
    message names itself; None when the caller must say (the default).
    """

    def __init__(self, message: str, *, parameter: str | None = None):
        super().__init__(message)
        self.parameter = parameter


class ConvergenceError(PushbroomError):
    """An iterative solution did not converge; the message says what was tried."""


class NoDescentError(ConvergenceError):
    """No step lowers the residuals: the normal matrix is (nearly) singular for the model chosen."""


class ConsistencyError(PushbroomError):
    """A result failed its own check (e.g. the adjusted scene as written does not image the points
    where the adjustment fitted them): nothing is written; the message names the cause."""


class Cancelled(PushbroomError):
    """The user cancelled a long computation; nothing was written."""
