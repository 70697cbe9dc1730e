"""Is a filter's covariance honest? The normalised estimation error squared (NEES) and its chi-square band.

For an estimate ``x̂`` of a d-dimensional truth ``x`` with covariance ``P``, the NEES is
``ε = (x̂ - x)ᵀ P⁻¹ (x̂ - x)``. If the filter is consistent (unbiased, ``P`` the true error covariance,
errors Gaussian), ``ε ~ χ²(d)``, mean d. Averaged at one time over M independent runs (Monte-Carlo
seeds), ``M·ε̄ ~ χ²(M·d)``, so ``ε̄`` lies in ``[χ²_{M·d}(0.025), χ²_{M·d}(0.975)] / M`` with
probability 95 %; an average above the band says the filter is overconfident (its covariance too
small for its errors), below it too cautious (Bar-Shalom, Li & Kirubarajan 2001, Estimation with
Applications to Tracking and Navigation, Sec. 5.4.2).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2


def nees(errors: np.ndarray, covariances: np.ndarray) -> np.ndarray:
    """``eᵀ P⁻¹ e`` of (..., d) ``errors`` (estimate minus truth) and their (..., d, d) covariances."""
    errors = np.asarray(errors, dtype=float)
    covariances = np.asarray(covariances, dtype=float)
    if covariances.shape != (*errors.shape, errors.shape[-1]):
        raise ValueError(
            f"covariances of shape {covariances.shape} do not match errors of shape {errors.shape}; "
            f"allowed: {(*errors.shape, errors.shape[-1])}"
        )
    solved = np.linalg.solve(covariances, errors[..., None])[..., 0]
    return np.einsum("...i,...i->...", errors, solved)


def average_nees_band(runs: int, dimension: int, probability: float = 0.95) -> tuple[float, float]:
    """The two-sided ``probability`` band of the NEES averaged over ``runs`` independent runs of a
    consistent filter of a ``dimension``-dimensional state: ``χ²_{M·d}((1 ∓ p)/2) / M`` (module
    docstring)."""
    for name, value in (("runs", runs), ("dimension", dimension)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name}={value!r} must be an integer >= 1")
    if not 0.0 < probability < 1.0:
        raise ValueError(f"probability={probability!r} must be in (0, 1)")
    tail = 0.5 * (1.0 - probability)
    low, high = chi2.ppf((tail, 1.0 - tail), runs * dimension) / runs
    return float(low), float(high)
