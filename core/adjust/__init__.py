"""Self-calibrating bundle adjustment: :func:`adjust` (:mod:`core.adjust.engine`) runs the stages
(checks, problem, determinability, solver with variance components and robust weights, interior
selection, statistics, check points, results)."""
from .engine import adjust
from .results import AdjustmentResult
from .settings import AdjustmentSettings

__all__ = ["AdjustmentResult", "AdjustmentSettings", "adjust"]
