"""The parameters' covariance from the whitened Jacobian, computed so that it holds.

Why not ``pinv(J^T J)``: the columns of a calibration Jacobian span ten or more orders of magnitude (a joint offset
moves the tool by metres per radian, a compliance by millimetres per newton metre per ... ), so ``J^T J`` squares a
condition number that is already large in raw units.  Its pseudo-inverse then loses every small direction to
rounding, and what comes back is not even positive semi-definite: the correlations printed from it reached 1.18 and
3.85 on real data.  Here the columns are scaled to unit length first (units drop out), the scaled Jacobian is
decomposed by SVD (no squaring), and the covariance is rebuilt from its singular vectors: symmetric and positive
semi-definite by construction, so every correlation lies in [-1, 1].

A direction the data do not determine (singular value ratio below :data:`UNDETERMINED_RTOL`) is left out of the
inverse and *named* instead (:class:`calib.identifiability.Combination`, in words): a variance of 1e12 is never a
result.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .identifiability import Combination, small_factor

#: singular value ratio (column-scaled Jacobian) below which a direction is reported as not determined
UNDETERMINED_RTOL = 1e-7


@dataclass
class Covariance:
    """``matrix`` over the columns of the Jacobian it came from (unscaled units), and the directions left out."""

    matrix: np.ndarray
    undetermined: list = field(default_factory=list)      # calib.identifiability.Combination


def from_jacobian(J: np.ndarray, names: list[str], rtol: float = UNDETERMINED_RTOL) -> Covariance:
    """``(J^T J)^-1`` of a whitened Jacobian ``J (m, p)`` over the determined directions (see the module docstring)."""
    p = J.shape[1]
    if p == 0:
        return Covariance(np.zeros((0, 0)))
    norms = np.linalg.norm(J, axis=0)
    d = np.where(norms > 0, norms, 1.0)
    # the singular values and right vectors of a tall J are those of its R factor (J = QR, Q orthonormal): one QR and
    # a p x p SVD cost a third of the SVD of J (the left vectors, which are not needed, are most of that)
    _, s, Vt = np.linalg.svd(small_factor(J / d), full_matrices=False)
    top = s[0] if s.size and s[0] > 0 else 1.0
    keep = s > rtol * top
    V = Vt[keep].T / s[keep]
    C = (V @ V.T) / np.outer(d, d)
    C = 0.5 * (C + C.T)
    gone = [Combination({n: float(v) for n, v in zip(names, row) if abs(v) > 1e-3}, float(sv / top))
            for sv, row in zip(s[~keep], Vt[~keep])]
    gone += [Combination({names[i]: 1.0}, 0.0) for i in np.flatnonzero(norms == 0)]
    return Covariance(C, gone)


def involved(undetermined: list, share: float = 0.1) -> set[str]:
    """The parameters carrying at least ``share`` of an undetermined direction (their sigma is not a number)."""
    out: set[str] = set()
    for c in undetermined:
        big = max((abs(v) for v in c.coefficients.values()), default=0.0)
        out |= {n for n, v in c.coefficients.items() if abs(v) >= share * big}
    return out


def correlation(cov: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance; NaN where a variance is zero; clipped to [-1, 1] against rounding."""
    d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        R = cov / np.outer(d, d)
    R = np.where(np.outer(d, d) > 0, np.clip(R, -1.0, 1.0), np.nan)
    np.fill_diagonal(R, np.where(d > 0, 1.0, np.nan))
    return R
