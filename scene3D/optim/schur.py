"""The damped normal equations of bundle adjustment, solved with the points eliminated.

Every observation ``o`` (a pixel, 2 residual rows) depends on at most one camera,
``camera[o]`` (``-1``: a fixed camera, no unknowns), and on one point,
``point[o]``. With the Jacobian blocks ``J_cam[o]`` ``(2, c)`` and ``J_point[o]``
``(2, 3)`` the normal equations are

    [ U   W ] [dc]     [g_c]
    [ W^T V ] [dp] = - [g_p]

with ``U`` block-diagonal over cameras and ``V`` block-diagonal over points
(3x3 each). Eliminating the points (Schur complement, Triggs et al. 2000,
section 6.1) leaves one ``(C c) x (C c)`` system for the cameras, then each
point's step is a 3x3 solve: the cost grows linearly with the points (times the
square of the cameras), not with the cube of all unknowns as a dense solve would.
From :data:`LARGE_SCHUR_CAMERAS` cameras on, the reduced system keeps only the blocks of
cameras that share points (:func:`schur_matrix_sparse`) and is factored sparsely, or solved
by conjugate gradients: its cost then grows with the observations, not with the cube of
the cameras.

Global unknowns (``g`` of them, such as one focal length shared by every view) may
join: every observation depends on them, fixed cameras' included, through
``J_global[o]`` ``(2, g)``. They add one block row and column to the reduced system,
outside the per-point blocks:

    [ U    U_cg  W  ] [dc]     [g_c]
    [ U_gc U_gg  W_g] [dg] = - [g_g]
    [ W^T  W_g^T V  ] [dp]     [g_p]

so eliminating the points leaves a ``(C c + g)`` system whose extra blocks are
``U_cg - sum_p W_p V_p^-1 W_gp^T`` and ``U_gg - sum_p W_gp V_p^-1 W_gp^T``.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ..geometry.conventions import FloatArray
from .conjugate_gradients import ConjugateGradientsResult, preconditioned_conjugate_gradients
from .schur_products import (  # noqa: F401 - the products, from here as before
    SPARSE_SCHUR_UNKNOWNS,
    pairs_within_groups,
    schur_matrix_sparse,
    schur_product,
    schur_product_dense,
    schur_product_sparse,
)

logger = logging.getLogger(__name__)

#: Added to the diagonals so that an unconstrained direction cannot make them singular.
_TINY = 1e-12


@dataclass(frozen=True)
class NormalEquations:
    """The blocks of ``J^T J`` and ``J^T r`` (see the module docstring).

    Attributes
    ----------
    U : (C, c, c)
    V : (P, 3, 3)
    W : (O', c, 3)
        One block per observation of a free camera (``observed`` selects them).
    g_camera : (C, c)
    g_point : (P, 3)
    camera, point : (O',) int
        The camera and point of each block of ``W``.
    U_global : (g, g) or None
        Global unknowns (see the module docstring); None when there are none.
    U_camera_global : (C, c, g) or None
    W_global : (P, g, 3) or None
    g_global : (g,) or None
    """

    U: FloatArray
    V: FloatArray
    W: FloatArray
    g_camera: FloatArray
    g_point: FloatArray
    camera: np.ndarray
    point: np.ndarray
    U_global: FloatArray | None = None
    U_camera_global: FloatArray | None = None
    W_global: FloatArray | None = None
    g_global: FloatArray | None = None


def _sum_by(index: np.ndarray, values: FloatArray, count: int) -> FloatArray:
    """``out[i] = sum of values[k] where index[k] == i``, ``i < count`` (a fast ``np.add.at``)."""
    flat = values.reshape(len(values), -1)
    out = np.empty((count, flat.shape[1]))
    for k in range(flat.shape[1]):
        out[:, k] = np.bincount(index, weights=flat[:, k], minlength=count)
    return out.reshape((count,) + values.shape[1:])


def _gram(A: FloatArray, B: FloatArray) -> FloatArray:
    """``A[o]^T B[o]`` for each ``o``: ``(O, k, i), (O, k, j) -> (O, i, j)``."""
    return A.transpose(0, 2, 1) @ B


def normal_equations(
    J_camera: FloatArray, camera: np.ndarray, J_point: FloatArray, point: np.ndarray,
    residuals: FloatArray, num_cameras: int, num_points: int,
    J_global: FloatArray | None = None,
) -> NormalEquations:
    """Accumulate the normal equations of row-scaled Jacobians and residuals.

    Parameters
    ----------
    J_camera : (O, 2, c)
        Derivatives by the observing camera's unknowns (ignored where ``camera < 0``).
    camera, point : (O,) int
    J_point : (O, 2, 3)
    residuals : (O, 2)
    J_global : (O, 2, g), optional
        Derivatives by the global unknowns (every observation, fixed cameras' too).
    """
    free = camera >= 0
    Jc, cam = J_camera[free], camera[free]
    r = residuals[:, :, None]
    U, g_camera = _camera_sums(cam, Jc, residuals[free], num_cameras)
    ne = NormalEquations(
        U=U,
        V=_sum_by(point, _gram(J_point, J_point), num_points),
        W=_gram(Jc, J_point[free]),
        g_camera=g_camera,
        g_point=_sum_by(point, _gram(J_point, r)[:, :, 0], num_points),
        camera=cam, point=point[free])
    if J_global is None:
        return ne
    Jg = J_global
    return dataclasses.replace(
        ne, U_global=_gram(Jg, Jg).sum(axis=0),
        U_camera_global=_sum_by(cam, _gram(Jc, Jg[free]), num_cameras),
        W_global=_sum_by(point, _gram(Jg, J_point), num_points),
        g_global=_gram(Jg, r)[:, :, 0].sum(axis=0))


def _camera_sums(camera: np.ndarray, J: FloatArray, residuals: FloatArray, num_cameras: int
                 ) -> tuple[FloatArray, FloatArray]:
    """``U = sum J[o]^T J[o]`` ``(C, c, c)`` and ``g = sum J[o]^T r[o]`` ``(C, c)`` by camera:
    one matrix product per camera over its observations' rows stacked (a few hundred
    cameras at most, thousands of rows each)."""
    c = J.shape[2]
    order = np.argsort(camera, kind="stable")
    J, residuals = J[order].reshape(-1, c), residuals[order].reshape(-1)
    bounds = 2 * np.searchsorted(camera[order], np.arange(num_cameras + 1))
    U, g = np.zeros((num_cameras, c, c)), np.zeros((num_cameras, c))
    for k in np.flatnonzero(np.diff(bounds)):
        rows = J[bounds[k]:bounds[k + 1]]
        U[k] = rows.T @ rows
        g[k] = rows.T @ residuals[bounds[k]:bounds[k + 1]]
    return U, g


def _damped_inverse_points(ne: NormalEquations, damping: float) -> FloatArray:
    """``(V + damping diag(V))^-1`` per point ``(P, 3, 3)``."""
    return np.linalg.inv(ne.V + damping * (np.einsum("nii->ni", ne.V) + _TINY)[:, :, None]
                         * np.eye(3))


@dataclass(frozen=True)
class _ReducedParts:
    """What the dense and the iterative reduced systems share: the damped camera blocks,
    ``Y = W V^-1`` per observation, the right-hand side and the global unknowns' blocks."""

    U: FloatArray  # (C, c, c), damped
    Y: FloatArray  # (O', c, 3)
    rhs: FloatArray  # (C c + g,)
    S_cg: FloatArray | None  # (C, c, g)
    S_gg: FloatArray | None  # (g, g)


def _reduced_parts(ne: NormalEquations, damping: float, V_inv: FloatArray) -> _ReducedParts:
    num_cameras, c = ne.g_camera.shape
    eye_c = np.eye(c)
    U = ne.U + damping * (np.einsum("nii->ni", ne.U) + _TINY)[:, :, None] * eye_c
    Y = ne.W @ V_inv[ne.point]  # (O', c, 3): W V^-1 per observation
    rhs = _sum_by(ne.camera, (Y @ ne.g_point[ne.point][:, :, None])[:, :, 0],
                  num_cameras).ravel() - ne.g_camera.ravel()
    if ne.U_global is None:
        return _ReducedParts(U, Y, rhs, None, None)
    Yg = ne.W_global @ V_inv  # (P, g, 3): W_g V^-1 per point
    S_cg = ne.U_camera_global - _sum_by(ne.camera, Y @ ne.W_global[ne.point].transpose(0, 2, 1),
                                        num_cameras)
    S_gg = (ne.U_global + damping * np.diag(np.diag(ne.U_global) + _TINY)
            - (Yg @ ne.W_global.transpose(0, 2, 1)).sum(axis=0))
    rhs_g = (Yg @ ne.g_point[:, :, None])[:, :, 0].sum(axis=0) - ne.g_global
    return _ReducedParts(U, Y, np.r_[rhs, rhs_g], S_cg, S_gg)


def _reduced_system(ne: NormalEquations, damping: float, V_inv: FloatArray
                    ) -> tuple[FloatArray, FloatArray]:
    """The damped system left once the points are eliminated: the matrix
    ``(C c + g, C c + g)`` (cameras first, then the global unknowns) and its right-hand
    side ``(C c + g,)`` (the step solves ``S x = rhs``)."""
    num_cameras, c = ne.g_camera.shape
    parts = _reduced_parts(ne, damping, V_inv)
    S = -schur_product(parts.Y, ne.W, ne.camera, ne.point, num_cameras)  # U - W V^-1 W^T
    for k in range(num_cameras):
        S[k * c:(k + 1) * c, k * c:(k + 1) * c] += parts.U[k]
    if parts.S_cg is None:
        return S, parts.rhs
    g = len(parts.S_gg)
    size = num_cameras * c
    full = np.empty((size + g, size + g))
    full[:size, :size] = S
    full[:size, size:] = parts.S_cg.reshape(size, g)
    full[size:, :size] = full[:size, size:].T
    full[size:, size:] = parts.S_gg
    return full, parts.rhs


#: From this many free cameras on, :func:`solve_damped_global` (``method="auto"``) solves
#: the reduced camera system by :data:`LARGE_SCHUR_METHOD` instead of densely.
LARGE_SCHUR_CAMERAS = 250

#: How ``method="auto"`` solves a reduced camera system of many cameras.
LARGE_SCHUR_METHOD = "sparse"

#: The conjugate gradients stop once ``|rhs - S x| <= PCG_RELATIVE_TOLERANCE |rhs|``.
PCG_RELATIVE_TOLERANCE = 1e-10

#: How :func:`solve_damped_global` may solve the reduced camera system.
SCHUR_METHODS = ("auto", "dense", "sparse", "iterative")


def _reduced_system_sparse(ne: NormalEquations, parts: _ReducedParts) -> sparse.csr_matrix:
    """:func:`_reduced_system`'s matrix as a sparse matrix (the global unknowns' rows and
    columns dense within it)."""
    num_cameras, c = ne.g_camera.shape
    size = num_cameras * c
    S = sparse.block_diag(list(parts.U), format="csr") - schur_matrix_sparse(
        parts.Y, ne.W, ne.camera, ne.point, num_cameras)
    if parts.S_cg is None:
        return S
    S_cg = sparse.csr_matrix(parts.S_cg.reshape(size, -1))
    return sparse.bmat([[S, S_cg], [S_cg.T, sparse.csr_matrix(parts.S_gg)]], format="csr")


def _solve_reduced_iterative(ne: NormalEquations, damping: float, V_inv: FloatArray
                             ) -> ConjugateGradientsResult:
    """Conjugate gradients on the sparse reduced camera system, preconditioned by the
    inverses of its diagonal blocks (per camera, then the global unknowns')."""
    num_cameras, c = ne.g_camera.shape
    size = num_cameras * c
    parts = _reduced_parts(ne, damping, V_inv)
    S = _reduced_system_sparse(ne, parts)
    W_t = ne.W.transpose(0, 2, 1)
    inverse = np.linalg.inv(parts.U - _sum_by(ne.camera, parts.Y @ W_t, num_cameras))
    inverse_g = None if parts.S_gg is None else np.linalg.inv(parts.S_gg)

    def precondition(r: FloatArray) -> FloatArray:
        out = (inverse @ r[:size].reshape(num_cameras, c, 1)).ravel()
        return out if inverse_g is None else np.r_[out, inverse_g @ r[size:]]

    result = preconditioned_conjugate_gradients(S.dot, parts.rhs, precondition,
                                                PCG_RELATIVE_TOLERANCE)
    logger.debug("conjugate gradients: %d iterations, relative residual %.1e%s (%d cameras)",
                 result.iterations, result.relative_residual,
                 "" if result.converged else " (not converged)", num_cameras)
    return result


def _solve_reduced_sparse(ne: NormalEquations, damping: float, V_inv: FloatArray
                          ) -> FloatArray:
    """The sparse reduced camera system solved directly (SuperLU, the fill-reducing
    ordering of ``S + S^T``: ``S`` is symmetric)."""
    parts = _reduced_parts(ne, damping, V_inv)
    S = _reduced_system_sparse(ne, parts)
    return splu(S.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(parts.rhs)


def solve_damped_global(ne: NormalEquations, damping: float, method: str = "auto"
                        ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Steps ``(C, c)`` for the cameras, ``(g,)`` for the global unknowns (empty without
    them) and ``(P, 3)`` for the points.

    Levenberg-Marquardt's damping scales the diagonals: ``U + damping diag(U)``
    and likewise ``V`` and ``U_gg``.

    The reduced camera system is formed and solved densely below
    :data:`LARGE_SCHUR_CAMERAS` free cameras; from there on (``method="auto"``) by
    :data:`LARGE_SCHUR_METHOD`. ``"sparse"`` stores only the blocks of cameras that
    share points (:func:`schur_matrix_sparse`) and factors them (SuperLU);
    ``"iterative"`` runs conjugate gradients on that matrix, preconditioned by its
    diagonal blocks
    (:func:`scene3D.optim.conjugate_gradients.preconditioned_conjugate_gradients`), to a
    relative residual of :data:`PCG_RELATIVE_TOLERANCE`. Both keep memory growing with
    the observations instead of the square of the cameras. With ``damping > 0`` the
    system is positive definite, the gauge (a scale a single fixed camera leaves free)
    included.

    Parameters
    ----------
    ne : NormalEquations
        The blocks of ``J^T J`` and ``J^T r``.
    damping : float
        Levenberg-Marquardt damping (0: Gauss-Newton).
    method : {"auto", "dense", "sparse", "iterative"}, default "auto"
        How to solve the reduced camera system ("auto": by the number of cameras).

    Returns
    -------
    step_camera : (C, c) float64 ndarray
    step_global : (g,) float64 ndarray
    step_point : (P, 3) float64 ndarray

    Raises
    ------
    ValueError
        For an unknown ``method``.
    """
    if method not in SCHUR_METHODS:
        raise ValueError(f"`method` must be one of {SCHUR_METHODS}, got {method!r}")
    num_cameras, c = ne.g_camera.shape
    V_inv = _damped_inverse_points(ne, damping)
    if method == "auto":
        method = LARGE_SCHUR_METHOD if num_cameras >= LARGE_SCHUR_CAMERAS else "dense"
    if method == "sparse":
        x = _solve_reduced_sparse(ne, damping, V_inv)
    elif method == "iterative":
        x = _solve_reduced_iterative(ne, damping, V_inv).x
    else:
        S, rhs = _reduced_system(ne, damping, V_inv)
        x = np.linalg.solve(S, rhs)
    size = num_cameras * c
    step_camera, step_global = x[:size].reshape(num_cameras, c), x[size:]
    back = ne.g_point + _sum_by(
        ne.point, _gram(ne.W, step_camera[ne.camera][:, :, None])[:, :, 0], len(ne.g_point))
    if ne.W_global is not None:
        back = back + (ne.W_global.transpose(0, 2, 1) @ step_global)
    step_point = -(V_inv @ back[:, :, None])[:, :, 0]
    return step_camera, step_global, step_point


def solve_damped(ne: NormalEquations, damping: float, method: str = "auto"
                 ) -> tuple[FloatArray, FloatArray]:
    """Steps ``(C, c)`` for the cameras and ``(P, 3)`` for the points
    (:func:`solve_damped_global` without global unknowns).

    Parameters
    ----------
    ne : NormalEquations
        The blocks of ``J^T J`` and ``J^T r``, without global unknowns.
    damping : float
        Levenberg-Marquardt damping (0: Gauss-Newton).
    method : {"auto", "dense", "sparse", "iterative"}, default "auto"
        How to solve the reduced camera system (see :func:`solve_damped_global`).

    Returns
    -------
    step_camera : (C, c) float64 ndarray
    step_point : (P, 3) float64 ndarray
    """
    step_camera, _, step_point = solve_damped_global(ne, damping, method)
    return step_camera, step_point


def global_information(ne: NormalEquations) -> FloatArray:
    """Information ``(g, g)`` of the global unknowns, the cameras and points marginalised:
    the reduced system's global block after the cameras are eliminated too (undamped;
    with residuals in units of their standard deviation its inverse is the covariance).

    The cameras' block may be singular along the gauge (the scale a single fixed camera
    leaves free); a gauge direction moves no residual, so it does not couple to the
    global unknowns and a pseudo-inverse there gives the same marginal as any gauge fixing.

    Parameters
    ----------
    ne : NormalEquations
        The blocks of ``J^T J`` and ``J^T r``, with global unknowns.

    Returns
    -------
    (g, g) float64 ndarray

    Raises
    ------
    ValueError
        If ``ne`` has no global unknowns.
    """
    if ne.U_global is None:
        raise ValueError("the normal equations have no global unknowns")
    V_inv = np.linalg.pinv(ne.V, hermitian=True)  # a point without observations: zero
    S, _ = _reduced_system(ne, 0.0, V_inv)
    g = len(ne.U_global)
    size = len(S) - g
    S_cc, S_cg, S_gg = S[:size, :size], S[:size, size:], S[size:, size:]
    return S_gg - S_cg.T @ np.linalg.pinv(S_cc, rcond=1e-12, hermitian=True) @ S_cg
