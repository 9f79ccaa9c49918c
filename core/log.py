"""A sentence for a run's log, as the core returns it: the caller writes it to its own log (the
Processing log in QGIS, naming its own parameter for the input a sentence is about)."""
from __future__ import annotations

from typing import NamedTuple


class LogLine(NamedTuple):
    """A sentence for the run's log. ``warning``: shown as a warning; ``parameter``: the input it
    concerns, in the core's terms (as :attr:`core.errors.InputError.parameter`: 'scene', 'dem'...),
    for the caller to name; None: none."""
    text: str
    warning: bool = False
    parameter: str | None = None
