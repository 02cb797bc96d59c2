"""Statistics of Monte Carlo campaigns: the Wilson interval of a success rate and the n-σ
ellipse of a landing footprint."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["wilson_interval", "footprint_ellipse"]


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054
                    ) -> tuple[float, float]:
    """Wilson score interval (95 % by default) of a success rate ``successes / n``."""
    if n <= 0:
        return (float("nan"), float("nan"))
    p = successes / n
    den = 1.0 + z * z / n
    center = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    # exact ends at 0 and n (the formula gives them only to rounding)
    return (0.0 if successes == 0 else max(0.0, center - half),
            1.0 if successes == n else min(1.0, center + half))


def footprint_ellipse(offsets_m: np.ndarray, n_sigma: float = 3.0) -> dict[str, float] | None:
    """The ``n_sigma`` ellipse of landing points (k, 2) (downrange, crossrange, m): centre,
    semi-axes (m) and the major axis's angle from downrange (deg); None with < 3 points."""
    pts = np.asarray(offsets_m, dtype=np.float64)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) < 3:
        return None
    mean = pts.mean(axis=0)
    w, v = np.linalg.eigh(np.cov(pts.T))
    w = np.maximum(w, 0.0)
    major = v[:, 1]
    return {"center_downrange_m": float(mean[0]), "center_crossrange_m": float(mean[1]),
            "semi_major_m": float(n_sigma * math.sqrt(w[1])),
            "semi_minor_m": float(n_sigma * math.sqrt(w[0])),
            "angle_deg": float(math.degrees(math.atan2(major[1], major[0]))),
            "n_sigma": float(n_sigma), "points": int(len(pts))}
