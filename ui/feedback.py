"""The core's errors, log, progress and cancellation in Processing terms: a core
:class:`core.errors.PushbroomError` becomes a QgsProcessingException naming the parameter at
fault, a core logger's messages go to the Processing log, a QgsProcessingFeedback becomes the
core's progress and cancel callbacks."""
from __future__ import annotations

import logging
from contextlib import contextmanager
from typing import Callable, Iterable, Mapping

from qgis.core import QgsProcessingException

from ..core.errors import PushbroomError


def error_message(error: PushbroomError, prefix: str = "", parameters: Mapping[str, str] | None = None) -> str:
    """The message of a core error for the user. When the error names the input it concerns
    (:attr:`core.errors.InputError.parameter`, in the core's terms) and ``parameters`` maps that
    input to an algorithm parameter, the message starts with that parameter's name (once: the core's
    message may start with it already, e.g. 'ALPHA must be ...'); when it concerns several inputs
    (parameter ''), the message names them itself and gets no prefix; otherwise it starts with
    ``prefix``."""
    concerns = getattr(error, "parameter", None)
    if concerns == "":
        return str(error)
    if parameters is not None and concerns in parameters:
        name = parameters[concerns]
        return str(error) if str(error).split(":")[0].split(" ")[0] == name else f"{name}: {error}"
    return f"{prefix}{error}"


@contextmanager
def processing_errors(prefix: str = "", parameters: Mapping[str, str] | None = None):
    """Turn core.errors.PushbroomError raised inside the block into QgsProcessingException,
    with ``prefix`` (e.g. the parameter name) put before the core's message, or the parameter
    ``parameters`` maps the error's input to (:func:`error_message`)."""
    try:
        yield
    except PushbroomError as exc:
        raise QgsProcessingException(error_message(exc, prefix, parameters)) from None


def core_call(func: Callable, *args, **kw):
    """Call a core function; its PushbroomError becomes a QgsProcessingException."""
    with processing_errors():
        return func(*args, **kw)


class _ToFeedback(logging.Handler):
    """A logging handler that writes to a QgsProcessingFeedback: warnings as warnings, the rest as info."""

    def __init__(self, feedback):
        super().__init__(logging.INFO)
        self.feedback = feedback

    def emit(self, record):
        push = self.feedback.pushWarning if record.levelno >= logging.WARNING else self.feedback.pushInfo
        push(record.getMessage())


@contextmanager
def core_log_to(feedback, logger_name: str):
    """Show a core module's log messages (warnings about the input) in the Processing log."""
    logger = logging.getLogger(logger_name)
    handler = _ToFeedback(feedback)
    logger.addHandler(handler)
    previous = logger.level
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(previous)


def push_lines(feedback, lines: Iterable, parameters: Mapping[str, str] | None = None) -> None:
    """Write the core's log sentences (:class:`core.log.LogLine`: text, warning, the input
    it concerns) to the Processing log, in order; a sentence about an input ``parameters`` maps to
    an algorithm parameter starts with that parameter's name."""
    for line in lines:
        name = (parameters or {}).get(line.parameter)
        text = f"{name}: {line.text}" if name else line.text
        (feedback.pushWarning if line.warning else feedback.pushInfo)(text)


def feedback_callbacks(feedback) -> tuple[Callable[[float, str | None], None], Callable[[], bool]]:
    """(progress(fraction 0..1, message or None), is_cancelled()) for a QgsProcessingFeedback
    (or None, when an algorithm runs without one)."""
    def progress(fraction: float, message: str | None = None) -> None:
        if feedback is None:
            return
        feedback.setProgress(100.0 * min(max(float(fraction), 0.0), 1.0))
        if message:
            feedback.setProgressText(message)

    def is_cancelled() -> bool:
        return feedback is not None and feedback.isCanceled()

    return progress, is_cancelled


def check_cancelled(feedback) -> None:
    """Stop an algorithm between steps when the user cancelled it."""
    if feedback is not None and feedback.isCanceled():
        raise QgsProcessingException("cancelled by the user")
