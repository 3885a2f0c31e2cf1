"""Bundle adjustment of a radially distorting camera: the focal length and ``k1[, k2]``
refined with the cameras and points (:mod:`scene3D.geometry.lens`'s model), the
observations as photographed. Frames and unknowns as in :mod:`scene3D.optim.bundle`; the
focal length and the coefficients are global unknowns of the normal equations
(:mod:`scene3D.optim.schur`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.camera import with_focal
from ..geometry.conventions import FloatArray, rotations_from_vectors, skews
from .bundle import Observations, robust_noise_px, whitened_reweighting
from .least_squares import levenberg_marquardt, robust_cost
from .schur import global_information, normal_equations, solve_damped_global


def radial_projection(
    R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations, K: FloatArray,
    k: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Pixels of a radially distorting camera (:mod:`scene3D.geometry.lens`) at each
    observation and their derivatives.

    Parameters
    ----------
    R, t, points3d, obs
        As in :func:`bundle_adjust`.
    K : (3, 3)
        Focal length ``K[0, 0]`` (square pixels, no skew) and principal point.
    k : (m,)
        Radial coefficients ``k1[, k2]`` (m = 0, 1 or 2; 0 for a pinhole camera).

    Returns
    -------
    pixels : (O, 2)
    J_camera, J_point : (O, 2, 6), (O, 2, 3)
        As in :func:`reprojection_jacobians`.
    J_global : (O, 2, 1 + m)
        By ``log f`` and each coefficient.
    """
    f, c = float(K[0, 0]), K[:2, 2]
    R_obs = R[obs.view]
    rotated = np.einsum("oij,oj->oi", R_obs, points3d[obs.point])
    cam = rotated + t[obs.view]
    z = cam[:, 2:3]
    n = cam[:, :2] / z
    r2 = np.sum(n * n, axis=1)
    powers = (np.stack([r2 ** (i + 1) for i in range(len(k))], axis=1) if len(k)
              else np.zeros((len(r2), 0)))  # (O, m)
    d = 1.0 + powers @ k
    dd_dr2 = sum(((i + 1) * k[i] * r2**i for i in range(len(k))), np.zeros_like(r2))
    # pixel = c + f d(r2) n: d pixel / d n = f (d I + 2 d'(r2) n n^T).
    J_n = f * (d[:, None, None] * np.eye(2) + 2.0 * dd_dr2[:, None, None]
               * n[:, :, None] * n[:, None, :])
    dn_dcam = np.zeros((len(n), 2, 3))
    dn_dcam[:, 0, 0] = dn_dcam[:, 1, 1] = 1.0 / z[:, 0]
    dn_dcam[:, :, 2] = -n / z
    J = J_n @ dn_dcam
    J_camera = np.concatenate([J @ -skews(rotated), J], axis=2)
    pixels = c + f * d[:, None] * n
    J_global = np.concatenate([(pixels - c)[:, :, None],
                               f * n[:, :, None] * powers[:, None, :]], axis=2)
    return pixels, J_camera, J @ R_obs, J_global


@dataclass(frozen=True)
class RadialAdjustment:
    """What :func:`bundle_adjust_radial` returns.

    Attributes
    ----------
    R, t, points3d : (V, 3, 3), (V, 3), (P, 3)
        Refined copies.
    K : (3, 3)
        The intrinsics with the refined focal length (principal point kept).
    k : (m,)
        The refined radial coefficients.
    sigma : (1 + m,)
        Standard deviations of ``log f`` and each coefficient (cameras and points
        marginalised, the priors included), in the noise of the residuals.
    noise_px : float
        Robust standard deviation of the final residuals.
    """

    R: FloatArray
    t: FloatArray
    points3d: FloatArray
    K: FloatArray
    k: FloatArray
    sigma: FloatArray
    noise_px: float


def bundle_adjust_radial(
    R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations, K: FloatArray,
    k: FloatArray, fixed_view: int | Sequence[int], prior_focal_px: float,
    prior_sigma_log: float, k_sigma: float = 0.5, loss: str = "soft_l1",
    scale_px: float = 1.0, max_iterations: int = 50, tolerance: float = 1e-10,
) -> RadialAdjustment:
    """:func:`bundle_adjust_focal` with radial distortion coefficients refined too.

    The observations are pixels of the distorting camera (as photographed); the
    unknowns besides the cameras and points are ``log f`` and ``k1[, k2]``, global
    unknowns of the normal equations. Priors: ``log f`` as in
    :func:`bundle_adjust_focal`, each coefficient ``N(0, k_sigma^2)`` (weak: it holds
    the coefficients only where the views do not determine them), both in units of the
    reprojection noise. One camera of :func:`bundle_adjust_cameras`.

    Parameters
    ----------
    R, t, points3d, obs, fixed_view, loss, scale_px, max_iterations, tolerance
        As in :func:`bundle_adjust`.
    K : (3, 3)
        Starting intrinsics (square pixels, no skew; the principal point is held).
    k : (m,)
        Starting coefficients, m = 1 (``simple_radial``) or 2 (``radial``).
    prior_focal_px, prior_sigma_log : float
        The focal length's prior, as in :func:`bundle_adjust_focal`.
    k_sigma : float
        The coefficients' prior standard deviation.

    Returns
    -------
    RadialAdjustment
    """
    k0 = np.atleast_1d(np.asarray(k, np.float64))
    if k0.size not in (1, 2):
        raise ValueError(f"one or two radial coefficients, got {k0.size}")
    fit = bundle_adjust_cameras(
        R, t, points3d, obs, np.asarray(K, np.float64)[None], k0[None],
        np.zeros(len(R), dtype=int), fixed_view, [prior_focal_px], [prior_sigma_log],
        k_sigma, loss, scale_px, max_iterations, tolerance)
    return RadialAdjustment(fit.R, fit.t, fit.points3d, fit.K[0], fit.k[0], fit.sigma[0],
                            fit.noise_px)


@dataclass(frozen=True)
class CamerasAdjustment:
    """What :func:`bundle_adjust_cameras` returns.

    Attributes
    ----------
    R, t, points3d : (V, 3, 3), (V, 3), (P, 3)
        Refined copies.
    K : (C, 3, 3)
        Each camera's intrinsics with its refined focal length (principal point kept).
    k : (C, m)
        Each camera's refined radial coefficients (m = 0: pinhole cameras).
    sigma : (C, 1 + m)
        Standard deviations of each camera's ``log f`` and coefficients (cameras and
        points marginalised, the priors included), in the noise of the residuals.
    noise_px : float
        Robust standard deviation of the final residuals.
    """

    R: FloatArray
    t: FloatArray
    points3d: FloatArray
    K: FloatArray
    k: FloatArray
    sigma: FloatArray
    noise_px: float


def bundle_adjust_cameras(
    R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations, K: FloatArray,
    k: FloatArray, view_camera: ArrayLike, fixed_view: int | Sequence[int],
    prior_focal_px: ArrayLike, prior_sigma_log: ArrayLike, k_sigma: float = 0.5,
    loss: str = "soft_l1", scale_px: float = 1.0, max_iterations: int = 50,
    tolerance: float = 1e-10,
) -> CamerasAdjustment:
    """Bundle adjustment of views from several radially distorting cameras: each
    camera's focal length and ``m`` radial coefficients refined with the poses and points.

    Each view ``v`` is taken by camera ``view_camera[v]``, whose pixels are
    :func:`radial_projection`'s (its own principal point, held). The unknowns besides
    the poses and points are every camera's ``log f`` and coefficients, global unknowns
    of the normal equations; priors as in :func:`bundle_adjust_radial`, per camera. A
    camera no observation sees keeps its start (its prior holds it).

    Parameters
    ----------
    R, t, points3d, obs, fixed_view, loss, scale_px, max_iterations, tolerance
        As in :func:`scene3D.optim.bundle.bundle_adjust`.
    K : (C, 3, 3)
        Each camera's starting intrinsics (square pixels, no skew).
    k : (C, m)
        Each camera's starting coefficients, m = 0, 1 or 2.
    view_camera : (V,) int array_like
        The camera of each view.
    prior_focal_px, prior_sigma_log : (C,) array_like
        Each camera's focal-length prior, as in
        :func:`scene3D.optim.bundle.bundle_adjust_focal`.
    k_sigma : float
        The coefficients' prior standard deviation.

    Returns
    -------
    CamerasAdjustment
    """
    K = np.asarray(K, np.float64).reshape(-1, 3, 3)
    C = len(K)
    k0 = np.asarray(k, np.float64).reshape(C, -1)
    m = k0.shape[1]
    prior_f = np.asarray(prior_focal_px, np.float64).reshape(C)
    prior_s = np.asarray(prior_sigma_log, np.float64).reshape(C)
    if m > 2:
        raise ValueError(f"at most two radial coefficients, got {m}")
    if not (np.all(np.isfinite(prior_f)) and np.all(prior_f > 0) and np.all(prior_s > 0)
            and k_sigma > 0):
        raise ValueError(f"the priors must be positive, got {prior_f.tolist()} px "
                         f"+-{prior_s.tolist()} (log), k +-{k_sigma}")
    camera_of_view = np.asarray(view_camera, dtype=int)
    obs_camera = camera_of_view[obs.view]
    free = np.setdiff1d(np.unique(obs.view), np.atleast_1d(np.asarray(fixed_view, dtype=int)))
    slot = np.full(len(R), -1, dtype=int)
    slot[free] = np.arange(len(free))
    camera = slot[obs.view]
    width = 1 + m  # unknowns of one camera: log f, then its coefficients
    prior_mean = np.concatenate([np.log(prior_f)[:, None], np.zeros((C, m))], axis=1).ravel()
    prior_sigma = np.concatenate([prior_s[:, None], np.full((C, m), k_sigma)], axis=1).ravel()

    def whitened(pixels: FloatArray) -> FloatArray:
        r = pixels - obs.xy
        return r if obs.sigma is None else r / obs.sigma[:, None]

    def intrinsics(g: FloatArray) -> FloatArray:
        return np.stack([with_focal(K[c], float(np.exp(g[c * width]))) for c in range(C)])

    def project(R_: FloatArray, t_: FloatArray, X_: FloatArray, g: FloatArray):
        Ks, ks = intrinsics(g), g.reshape(C, width)[:, 1:]
        if C == 1:
            return radial_projection(R_, t_, X_, obs, Ks[0], ks[0])
        pixels = np.empty_like(obs.xy, dtype=np.float64)
        J_camera = np.empty((len(obs.xy), 2, 6))
        J_point = np.empty((len(obs.xy), 2, 3))
        J_global = np.zeros((len(obs.xy), 2, C * width))
        for c in range(C):
            rows = np.flatnonzero(obs_camera == c)
            if not len(rows):
                continue
            part = Observations(obs.view[rows], obs.point[rows], obs.xy[rows])
            p, Jc, Jp, Jg = radial_projection(R_, t_, X_, part, Ks[c], ks[c])
            pixels[rows], J_camera[rows], J_point[rows] = p, Jc, Jp
            J_global[rows, :, c * width:(c + 1) * width] = Jg
        return pixels, J_camera, J_point, J_global

    R0, t0 = np.array(R, np.float64), np.array(t, np.float64)
    X0 = np.array(points3d, np.float64)
    g0 = np.concatenate([np.log(K[:, 0, 0])[:, None], k0], axis=1).ravel()
    noise = robust_noise_px(whitened(project(R0, t0, X0, g0)[0]))
    prior_weight = noise / prior_sigma  # rebound below, as the noise settles

    def evaluate(R_: FloatArray, t_: FloatArray, X_: FloatArray, g: FloatArray):
        projected = project(R_, t_, X_, g)
        r_ = whitened(projected[0])
        cost = robust_cost(r_, loss, scale_px) + float(
            np.sum((prior_weight * (g - prior_mean)) ** 2))
        return (R_, t_, X_, g, r_, projected), cost

    def system(state: tuple):
        R_, t_, X_, g, r_, (_, J_camera, J_point, J_global) = state
        row_scale, rw = whitened_reweighting(r_, obs, loss, scale_px)
        scale = row_scale[:, :, None]
        ne = normal_equations(J_camera * scale, camera, J_point * scale, obs.point, rw,
                              len(free), len(X_), J_global * scale)
        return dataclasses.replace(
            ne, U_global=ne.U_global + np.diag(prior_weight**2),
            g_global=ne.g_global + prior_weight**2 * (g - prior_mean))

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, X_, g = state[:4]
        ne = system(state)

        def try_step(damping: float) -> tuple[tuple, float]:
            step_camera, step_global, step_point = solve_damped_global(ne, damping)
            R_new, t_new = R_.copy(), t_.copy()
            R_new[free] = rotations_from_vectors(step_camera[:, :3]) @ R_[free]
            t_new[free] = t_[free] + step_camera[:, 3:]
            return evaluate(R_new, t_new, X_ + step_point, g + step_global)

        return try_step

    # The priors weigh as one observation of the residuals' noise; a start far off
    # inflates it (and the priors' pull), so adjust again once it is known, as
    # bundle_adjust_focal does.
    for _ in range(3):
        state, cost = evaluate(R0, t0, X0, g0)
        state = levenberg_marquardt(state, cost, linearize, max_iterations, tolerance)
        R0, t0, X0, g0 = state[:4]
        settled = robust_noise_px(state[4])
        if settled > 0.5 * noise:
            break
        noise = settled
        prior_weight = noise / prior_sigma
    R_, t_, X_, g, r_, _ = state
    # The priors' rows are in units of the last noise; the data's information is in
    # the settled noise's, and the priors add theirs (the Schur complement leaves the
    # diagonal priors of global unknowns as they are).
    data = global_information(system(state)) - np.diag(prior_weight**2)
    info = data / max(settled, 1e-9) ** 2 + np.diag(1.0 / prior_sigma**2)
    sigma = np.sqrt(np.diag(np.linalg.pinv(info))).reshape(C, width)
    return CamerasAdjustment(R_, t_, X_, intrinsics(g), g.reshape(C, width)[:, 1:].copy(),
                             sigma, settled)
