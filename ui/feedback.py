"""The core's errors, log lines, progress and cancellation in Processing terms: a
:class:`core.errors.PushbroomError` becomes a QgsProcessingException naming the parameter at fault, a
:class:`core.log.LogLine` a Processing log line, a QgsProcessingFeedback the core's callbacks."""
from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterable, Mapping

from qgis.core import QgsProcessingException

from ..core.errors import PushbroomError


def error_message(error: PushbroomError, prefix: str = "", parameters: Mapping[str, str] | None = None) -> str:
    """A core error's message, starting with the algorithm parameter ``parameters`` maps its input
    (:attr:`core.errors.InputError.parameter`) to, once (the core may have named it: 'ALPHA must be ...');
    unchanged for an error about several inputs (parameter ''); else after ``prefix``."""
    concerns = getattr(error, "parameter", None)
    if concerns == "":
        return str(error)
    if parameters is not None and concerns in parameters:
        name = parameters[concerns]
        return str(error) if str(error).split(":")[0].split(" ")[0] == name else f"{name}: {error}"
    return f"{prefix}{error}"


@contextmanager
def processing_errors(prefix: str = "", parameters: Mapping[str, str] | None = None):
    """A core error raised inside becomes a QgsProcessingException of :func:`error_message`."""
    try:
        yield
    except PushbroomError as exc:
        raise QgsProcessingException(error_message(exc, prefix, parameters)) from None


def push_lines(feedback, lines: Iterable, parameters: Mapping[str, str] | None = None) -> None:
    """The core's log lines to the Processing log, in order; a line about an input ``parameters`` maps to
    an algorithm parameter starts with that parameter's name."""
    for line in lines:
        name = (parameters or {}).get(line.parameter)
        text = f"{name}: {line.text}" if name else line.text
        (feedback.pushWarning if line.warning else feedback.pushInfo)(text)


def feedback_callbacks(feedback) -> tuple[Callable[[float, str | None], None], Callable[[], bool]]:
    """(progress(fraction 0..1, message or None), is_cancelled()) of a QgsProcessingFeedback (or None)."""
    def progress(fraction: float, message: str | None = None) -> None:
        if feedback is None:
            return
        feedback.setProgress(100.0 * min(max(float(fraction), 0.0), 1.0))
        if message:
            feedback.setProgressText(message)

    def is_cancelled() -> bool:
        return feedback is not None and feedback.isCanceled()

    return progress, is_cancelled
