"""Preconditioned conjugate gradients for a symmetric positive definite system given by its product.

The reduced camera system of a bundle adjustment with many cameras is sparse (cameras that
share no point give zero blocks) but forming it densely costs the square of the cameras in
memory and their cube in the solve. Conjugate gradients need only products ``S x``; in
:mod:`scene3D.optim.schur` they are sparse matrix products and the preconditioner is the
inverse of each camera's diagonal block of ``S`` (Schur-Jacobi; Agarwal et al., "Bundle
adjustment in the large", ECCV 2010, as Ceres' ``ITERATIVE_SCHUR``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..geometry.conventions import FloatArray


@dataclass(frozen=True)
class ConjugateGradientsResult:
    """What :func:`preconditioned_conjugate_gradients` returns.

    Attributes
    ----------
    x : (n,) float64
        The solution.
    iterations : int
        Products ``S x`` taken.
    relative_residual : float
        ``|b - S x| / |b|`` at the end (0 for ``b = 0``).
    converged : bool
        Whether ``relative_residual`` reached the tolerance.
    """

    x: FloatArray
    iterations: int
    relative_residual: float
    converged: bool


def preconditioned_conjugate_gradients(
    apply: Callable[[FloatArray], FloatArray], b: FloatArray,
    precondition: Callable[[FloatArray], FloatArray], relative_tolerance: float = 1e-10,
    max_iterations: int | None = None,
) -> ConjugateGradientsResult:
    """Solve ``S x = b`` for a symmetric positive definite ``S`` (Hestenes-Stiefel, with a
    preconditioner ``M^-1 ~ S^-1``; Saad, "Iterative methods for sparse linear systems",
    algorithm 9.1), starting from ``x = 0``.

    Parameters
    ----------
    apply : callable
        ``apply(x) -> S x``, ``(n,) -> (n,)``.
    b : (n,) array_like
    precondition : callable
        ``precondition(r) -> M^-1 r``, ``(n,) -> (n,)``, symmetric positive definite.
    relative_tolerance : float, default 1e-10
        Stop once ``|b - S x| <= relative_tolerance |b|`` (the residual recurrence's norm,
        recomputed from ``apply`` every 50 iterations so that rounding cannot fake it).
    max_iterations : int, optional
        At most this many products (default ``n``, enough in exact arithmetic, at least 50).

    Returns
    -------
    ConjugateGradientsResult
    """
    b = np.asarray(b, dtype=np.float64)
    n = len(b)
    limit = max(n, 50) if max_iterations is None else max_iterations
    x = np.zeros(n)
    norm_b = float(np.linalg.norm(b))
    if norm_b == 0.0:
        return ConjugateGradientsResult(x, 0, 0.0, True)
    r = b.copy()
    z = precondition(r)
    p = z.copy()
    rz = float(r @ z)
    relative = 1.0
    iterations = 0
    while iterations < limit:
        q = apply(p)
        iterations += 1
        pq = float(p @ q)
        if not pq > 0.0:  # S not positive definite along p (or p = 0): nothing more to gain
            break
        alpha = rz / pq
        x += alpha * p
        if iterations % 50 == 0:  # the recurrence drifts from the true residual
            r = b - apply(x)
        else:
            r -= alpha * q
        relative = float(np.linalg.norm(r)) / norm_b
        if relative <= relative_tolerance:
            break
        z = precondition(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return ConjugateGradientsResult(x, iterations, relative, relative <= relative_tolerance)
