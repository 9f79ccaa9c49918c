"""Self-calibrating bundle adjustment (see :mod:`core.adjust.engine`)."""
from .engine import AdjustmentResult, AdjustmentSettings, adjust

__all__ = ["AdjustmentResult", "AdjustmentSettings", "adjust"]
