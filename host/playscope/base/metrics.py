"""Error figures the evaluations share: root mean square of residuals.

`rmse` lets a NaN through (a residual that could not be computed makes the figure NaN, so a
table shows it instead of hiding a hole); `rmse_finite` is over the finite residuals only (a
reference trajectory whose inverse is undefined at a few samples).
"""

from __future__ import annotations

import numpy as np


def rmse(e) -> float:
    """Root mean square of the residuals e (any shape), in e's unit; NaN if any is NaN."""
    return float(np.sqrt(np.mean(np.square(e))))


def rmse_finite(e) -> float:
    """Root mean square over the finite residuals of e (any shape), in e's unit; NaN if none is."""
    a = np.asarray(e, float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a * a))) if a.size else float("nan")
