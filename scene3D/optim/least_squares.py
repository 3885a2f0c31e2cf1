"""Robust least squares: the losses, the scaled normal equations and Levenberg-Marquardt's loop.

What every solver of scene3D shares (the Sampson refinement of a pose and its focal and
distortion variants in :mod:`scene3D.optim.refinement`, the bundle adjustments of two views
in :mod:`scene3D.optim.bundle_two_view` and of many in :mod:`scene3D.optim.bundle`):

- :func:`robust_loss`: scipy's robust losses ``rho(z)`` and their first two derivatives;
- :func:`robust_cost`: ``scale^2 sum rho((r / scale)^2)``, the cost all of them minimise;
- :func:`robust_scaling` (the loss's curvature in the normal equations, as scipy's
  ``least_squares``) and :func:`reweighting` (iteratively reweighted least squares, as
  Ceres): the row scales of the Jacobian and the scaled residuals;
- :func:`damped_steps`: the damped Gauss-Newton steps of a small dense problem;
- :func:`robust_covariance`: the sandwich covariance of the robust fit at its optimum;
- :func:`levenberg_marquardt`: the outer loop (damping, acceptance, stopping), independent
  of how a problem stores its unknowns or solves its normal equations.

The losses are those of ``scipy.optimize.least_squares``: ``"linear"``, ``"huber"``,
``"soft_l1"`` and ``"cauchy"``, evaluated at ``z = (r / scale)^2``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..geometry.conventions import FloatArray
from .uncertainty import sandwich_covariance

#: The robust losses :func:`robust_loss` knows.
LOSSES = ("linear", "huber", "soft_l1", "cauchy")


def robust_loss(z: FloatArray, loss: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """scipy's robust loss ``rho(z)`` and its derivatives ``rho'``, ``rho''`` at ``z = r^2``.

    Parameters
    ----------
    z : (...) array
        Squared scaled residuals, ``(r / scale)^2 >= 0``.
    loss : str
        One of :data:`LOSSES`.

    Returns
    -------
    rho, rho1, rho2 : (...) float64
        The loss and its first and second derivatives by ``z``, each of ``z``'s shape.

    Raises
    ------
    ValueError
        For an unknown ``loss``.
    """
    if loss == "linear":
        return z, np.ones_like(z), np.zeros_like(z)
    if loss == "cauchy":
        rho1 = 1.0 / (1.0 + z)
        return np.log1p(z), rho1, -(rho1**2)
    if loss == "soft_l1":
        rho1 = 1.0 / np.sqrt(1.0 + z)
        return 2.0 * (np.sqrt(1.0 + z) - 1.0), rho1, -0.5 * rho1**3
    if loss == "huber":
        big = z > 1.0
        zs = np.maximum(z, 1e-300)
        return (np.where(big, 2.0 * np.sqrt(zs) - 1.0, z),
                np.where(big, 1.0 / np.sqrt(zs), 1.0),
                np.where(big, -0.5 / (zs * np.sqrt(zs)), 0.0))
    raise ValueError(f"unknown loss {loss!r}; use linear, huber, soft_l1 or cauchy")


def robust_scaling(r: FloatArray, loss: str, scale: float) -> tuple[FloatArray, FloatArray]:
    """Row scales of the Jacobian and scaled residuals for a robust Gauss-Newton step.

    With ``z = (r / scale)^2`` and the loss ``rho(z)`` (:func:`robust_loss`), the rows of
    ``J`` are scaled by ``sqrt(rho' + 2 rho'' z)`` and the residuals become
    ``rho' r / sqrt(rho' + 2 rho'' z)`` (Triggs et al., "Bundle adjustment: a modern
    synthesis", section 4.3, as in scipy's ``least_squares``): the normal equations
    then hold the robust cost's gradient and a Hessian that includes the curvature
    of the loss, which converges in fewer steps than plain reweighting.

    Parameters
    ----------
    r : (N,) array
        Residuals, in the unit of ``scale``.
    loss : str
        One of :data:`LOSSES`.
    scale : float
        The loss's scale (pixels for the refinements).

    Returns
    -------
    row_scale, scaled_residuals : (N,) float64
    """
    z = (r / scale) ** 2
    _, rho1, rho2 = robust_loss(z, loss)
    row_scale = np.sqrt(np.maximum(rho1 + 2.0 * rho2 * z, np.finfo(float).eps))
    return row_scale, rho1 * r / row_scale


def reweighting(r: FloatArray, loss: str, scale: float) -> tuple[FloatArray, FloatArray]:
    """Row scales ``sqrt(rho')`` of the Jacobian and scaled residuals ``sqrt(rho') r``.

    Iteratively reweighted least squares, as Ceres does for losses whose curvature
    ``rho''`` is negative (all of :data:`LOSSES`): the gradient is the robust cost's, and the
    Hessian stays positive for every row. Bundle adjustment needs this: a point has
    only four rows, and where all of them are past the loss's scale the curvature-
    corrected rows of :func:`robust_scaling` (clamped at zero, as in scipy) leave its
    3x3 block singular, so no damped step can move it, or the pose with it.

    Parameters
    ----------
    r : (...) array
        Residuals, in the unit of ``scale``.
    loss : str
        One of :data:`LOSSES`.
    scale : float

    Returns
    -------
    row_scale, scaled_residuals : (...) float64
        Each of ``r``'s shape.
    """
    _, rho1, _ = robust_loss((r / scale) ** 2, loss)
    row_scale = np.sqrt(rho1)
    return row_scale, row_scale * r


def damped_steps(J: FloatArray, r: FloatArray, loss: str,
                 scale: float) -> Callable[[float], FloatArray]:
    """Steps of robust Gauss-Newton on residuals ``r`` with Jacobian ``J``.

    Builds the normal equations once, with the rows of :func:`robust_scaling`, and
    returns ``step(damping) -> dx`` with Marquardt's damping of their diagonal.

    Parameters
    ----------
    J : (N, k) array
        Jacobian of the residuals by the ``k`` unknowns.
    r : (N,) array
        Residuals.
    loss : str
        One of :data:`LOSSES`.
    scale : float

    Returns
    -------
    step : callable
        ``step(damping: float) -> (k,) float64``, the step that lowers the linearised cost.
    """
    row_scale, rw = robust_scaling(r, loss, scale)
    Jw = J * row_scale[:, None]
    H, g = Jw.T @ Jw, Jw.T @ rw
    damped = np.diag(np.diag(H) + 1e-12)
    return lambda damping: np.linalg.solve(H + damping * damped, -g)


def robust_covariance(J: FloatArray, r: FloatArray, loss: str, scale: float) -> FloatArray:
    """Covariance of the robust fit whose residuals ``r`` have Jacobian ``J`` at the optimum.

    The cost ``scale^2 rho((r / scale)^2)`` has the influence ``psi = rho' r`` and
    its slope ``psi' = rho' + 2 rho'' z`` (the row scales of :func:`robust_scaling`,
    squared, here without their clamp at zero);
    :func:`scene3D.optim.uncertainty.sandwich_covariance` makes the sandwich of them.

    Parameters
    ----------
    J : (N, k) array
    r : (N,) array
    loss : str
        One of :data:`LOSSES`.
    scale : float

    Returns
    -------
    (k, k) float64
        Infinite when the residuals do not determine the unknowns.
    """
    z = (r / scale) ** 2
    _, rho1, rho2 = robust_loss(z, loss)
    return sandwich_covariance(J, rho1 * r, rho1 + 2.0 * rho2 * z)


def robust_cost(r: FloatArray, loss: str, scale: float) -> float:
    """``scale^2 * sum rho((r / scale)^2)``, the cost the refinements minimise.

    Parameters
    ----------
    r : (...) array
        Residuals, in the unit of ``scale``.
    loss : str
        One of :data:`LOSSES`.
    scale : float

    Returns
    -------
    float
        In the squared unit of ``r`` (``sum r^2`` for the linear loss).
    """
    return float(scale**2 * np.sum(robust_loss((r / scale) ** 2, loss)[0]))


def levenberg_marquardt(
    state: tuple, cost: float, linearize: Callable[[tuple], Callable[[float], tuple]],
    max_iterations: int, min_decrease: float,
) -> tuple:
    """Levenberg-Marquardt's outer loop: damping, acceptance and stopping.

    A step is accepted when it lowers the cost (then the damping falls tenfold, else it
    rises tenfold and the step is solved again); the loop stops when a step gains less
    than ``min_decrease`` of the cost, none can be found, or after ``max_iterations``.

    Parameters
    ----------
    state : tuple
        The problem's unknowns (and whatever it caches with them), in its own layout.
    cost : float
        The cost at ``state``.
    linearize : callable
        ``linearize(state)`` builds the normal equations at ``state`` and returns
        ``try_step(damping) -> (new_state, new_cost)``.
    max_iterations : int
        The most linearisations.
    min_decrease : float
        The relative decrease of the cost below which an accepted step ends the loop.

    Returns
    -------
    tuple
        The last accepted state (``state`` itself when no step lowered the cost).
    """
    damping = 1e-3
    for _ in range(max_iterations):
        try_step = linearize(state)
        improved = False
        while damping < 1e8:
            new_state, new_cost = try_step(damping)
            if new_cost < cost:
                improved = cost - new_cost > min_decrease * max(cost, 1e-30)
                state, cost = new_state, new_cost
                damping = max(damping / 10.0, 1e-9)
                break
            damping *= 10.0
        if not improved:
            break
    return state
