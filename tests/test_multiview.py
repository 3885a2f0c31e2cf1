"""Multi-view reconstruction: synthetic views with known cameras, then fountain-P11."""

import dataclasses
import json
import re
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest

from scene3D.errors import ReconstructionError
from scene3D.evaluation import camera_set_error, similarity_transform
from scene3D.geometry import (
    project,
    quaternion_from_rotation,
    rotation_about_axis,
    rotation_from_quaternion,
)
from scene3D.geometry.epipolar import essential_distances, essential_from_pose
from scene3D.multiview import (
    PairMatches,
    SfMSettings,
    ViewFeatures,
    build_tracks,
    check_model,
    extract_features,
    reconstruct_models,
    select_pairs,
    verify_pair,
)
from scene3D.optim.bundle import Observations, bundle_adjust, reprojection_residuals
from scene3D.optim.schur import schur_product_dense, schur_product_sparse

from .conftest import REPO
from .helpers import scipy_bundle_adjust

K = np.array([[800.0, 0, 330], [0, 780, 245], [0, 0, 1]])


def _ring_of_cameras(n=6):
    """Cameras on an arc looking at the origin region, world-to-camera poses."""
    Rs, ts = [], []
    for i in range(n):
        angle = -25 + 50 * i / (n - 1)
        R = rotation_about_axis([0.1, 1.0, 0.05], angle)
        center = np.array([8 * np.sin(np.radians(angle)), 0.3 * i - 0.5,
                           -8 * np.cos(np.radians(angle)) + 8])
        Rs.append(R)
        ts.append(-R @ center)
    return np.array(Rs), np.array(ts)


def _ring_views(rng, observe):
    """The ring's views of 500 random points and the verified pairs (every true
    correspondence): ``observe(rng, pixels)`` gives each view's keypoints from the exact
    pixels of its visible points, and their sizes (or None)."""
    points = rng.uniform([-3, -2, 6], [3, 2, 11], (500, 3))
    Rs, ts = _ring_of_cameras()
    features, ids = [], []
    for R, t in zip(Rs, ts):
        pix = project(points, K, R, t)
        visible = np.flatnonzero(np.all((pix > 0) & (pix < [660, 490]), axis=1))
        order = rng.permutation(visible)  # keypoint order unrelated to point ids
        keypoints, sizes = observe(rng, pix[order])
        features.append(ViewFeatures(keypoints, np.zeros((len(order), 1), np.float32),
                                     np.zeros((len(order), 3), np.uint8), sizes=sizes))
        ids.append(order)
    pairs = []
    for i, j in select_pairs(len(Rs), "all")[0]:
        _, a, b = np.intersect1d(ids[i], ids[j], return_indices=True)
        pairs.append(PairMatches(i, j, a, b, len(a)))
    return features, pairs, Rs, ts, points


def _synthetic_views(noise_px=0.0, seed=0):
    def observe(rng, pix):
        return (pix + rng.normal(0, noise_px, pix.shape) if noise_px else pix), None

    return _ring_views(np.random.default_rng(seed), observe)


@pytest.mark.parametrize("noise_px, center_tol, rot_tol_deg, rmse_tol", [
    (0.0, 1e-6, 1e-5, 1e-5),  # exact up to a similarity
    (0.5, 5e-3, 0.2, 0.8),
])
def test_synthetic_views_are_recovered_up_to_similarity(noise_px, center_tol, rot_tol_deg,
                                                        rmse_tol):
    features, pairs, Rs, ts, _ = _synthetic_views(noise_px)
    models, reasons, _ = reconstruct_models(features, pairs, K, SfMSettings())
    model = models[0]
    assert len(models) == 1 and model.registered.all() and reasons == {}
    centers_true = -np.einsum("vji,vj->vi", Rs, ts)
    err = camera_set_error(model.R, model.centers, Rs, centers_true)
    assert err.center_errors.max() < center_tol
    assert err.rotation_errors_deg.max() < rot_tol_deg
    res = reprojection_residuals(model.R, model.t, model.points3d, model.observations, K)
    assert np.sqrt(np.mean(res**2)) == pytest.approx(model.reprojection_rmse_px)
    assert model.reprojection_rmse_px < rmse_tol
    assert len(model.points3d) > 400
    assert model.check.ok and model.check.pairs_checked == len(pairs)


def test_false_two_view_matches_do_not_bend_the_cameras():
    """As many false matches as true ones between views 2 and 3, all consistent with
    view 3 turned by 0.2 deg (as the neighbouring windows of a repeated facade fit a
    slightly wrong epipolar geometry; castle-P19 0013-0014): they make two-view points
    that nothing contradicts. Adjusted on the points of three views or more, the cameras
    stay where the true matches put them; when every two-view point steers the
    adjustment too, view 3 follows the false matches."""
    features, pairs, Rs, ts, _ = _synthetic_views(0.3)
    rng = np.random.default_rng(3)
    extra = rng.uniform([-3, -2, 6], [3, 2, 11], (3000, 3))
    a, b = 2, 3
    R_wrong = rotation_about_axis([0.3, 1.0, -0.2], 0.2) @ Rs[b]
    pix_a, pix_b = project(extra, K, Rs[a], ts[a]), project(extra, K, R_wrong, ts[b])
    seen = np.all((pix_a > 0) & (pix_a < [660, 490]) & (pix_b > 0) & (pix_b < [660, 490]), 1)
    true_pair = next(p for p in pairs if (p.i, p.j) == (a, b))
    false = np.flatnonzero(seen)[:true_pair.num_inliers]
    added = {}
    for v, pix in ((a, pix_a[false]), (b, pix_b[false])):
        kp = np.vstack([features[v].keypoints, pix + rng.normal(0, 0.3, pix.shape)])
        added[v] = np.arange(len(features[v].keypoints), len(kp))
        features[v] = ViewFeatures(kp, np.zeros((len(kp), 1), np.float32),
                                   np.zeros((len(kp), 3), np.uint8))
    pairs = [PairMatches(a, b, np.r_[p.idx_i, added[a]], np.r_[p.idx_j, added[b]],
                         p.num_matches + len(false)) if p is true_pair else p for p in pairs]
    centers_true = -np.einsum("vji,vj->vi", Rs, ts)
    errors = {}
    for label, support in (("multi-view", SfMSettings().min_multiview_observations),
                           ("every point", 10**9)):
        models, _, _ = reconstruct_models(features, pairs, K,
                                          SfMSettings(min_multiview_observations=support))
        assert models[0].registered.all()
        errors[label] = camera_set_error(models[0].R, models[0].centers, Rs,
                                         centers_true).rotation_errors_deg
    assert errors["multi-view"].max() < 0.02
    assert errors["every point"][b] > 0.03  # the false matches do pull when admitted


def test_tracks_chain_matches_and_drop_inconsistent_ones():
    matches = {(0, 1): (np.array([0, 1]), np.array([5, 6])),
               (1, 2): (np.array([5, 6]), np.array([9, 9]))}  # 0:0 and 0:1 meet in 2:9
    tracks = build_tracks([3, 7, 10], matches)
    assert tracks.as_dicts() == [] and tracks.num_tracks == 0
    tracks = build_tracks([3, 7, 10], {(0, 1): (np.array([0, 2]), np.array([5, 1])),
                                       (1, 2): (np.array([5]), np.array([9]))})
    assert tracks.as_dicts() == [{0: 0, 1: 5, 2: 9}, {0: 2, 1: 1}]


@pytest.mark.parametrize("feature, norm", [("SIFT", cv2.NORM_L2), ("ORB", cv2.NORM_HAMMING)])
def test_views_carry_their_descriptor_norm_into_matching(rendered_pair, feature, norm):
    img1, img2, K, R, t = rendered_pair
    f1, f2 = extract_features(img1, feature), extract_features(img2, feature)
    assert f1.norm == f2.norm == norm
    found = verify_pair(f1, f2, K, SfMSettings())
    idx1, idx2 = found.idx_i, found.idx_j
    distances = essential_distances(essential_from_pose(R, t), f1.keypoints[idx1],
                                    f2.keypoints[idx2], K)
    assert len(idx1) >= 50 and np.median(distances) < 1.0  # within 1 px of the true geometry


def test_pair_selection():
    assert select_pairs(4, "all")[0] == [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    pairs, text = select_pairs(30, "sequential", neighbours=2)
    assert pairs[:3] == [(0, 1), (0, 2), (1, 2)] and "sequential" in text
    # 30 views on a circle: similar when close on it. In order, auto adds the sequence;
    # shuffled, the same retrieval pairs and no sequential ones.
    angle = 2 * np.pi * np.arange(30) / 30
    vlads = np.column_stack([np.cos(angle), np.sin(angle)])
    from scene3D.multiview import similarity_ranking

    ranking, _ = similarity_ranking(vlads)
    pairs, text = select_pairs(30, "auto", 3, ranking, retrieval_neighbours=4)
    assert "sequential" in text and (0, 3) in pairs and (0, 29) in pairs and (0, 15) not in pairs
    shuffled = np.random.default_rng(0).permutation(30)
    pairs_s, text_s = select_pairs(30, "auto", 3, ranking, 4, sequence=shuffled)
    assert "not a sequence" in text_s
    assert set(pairs_s) == set(select_pairs(30, "retrieval", 3, ranking, 4)[0])
    assert select_pairs(9, "auto", retrieval_neighbours=4)[1] == "all pairs (auto: 9 views)"
    with pytest.raises(ValueError, match="'auto', 'retrieval', 'sequential', 'all'"):
        select_pairs(3, "random")
    with pytest.raises(ValueError, match="similarity ranking"):
        select_pairs(30, "retrieval")


def test_bundle_adjustment_reduces_error_and_fixes_the_reference():
    features, pairs, Rs, ts, points = _synthetic_views()
    rng = np.random.default_rng(3)
    view, point, xy = [], [], []
    for v, (R, t) in enumerate(zip(Rs, ts)):
        pix = project(points, K, R, t)
        view += [v] * len(points)
        point += list(range(len(points)))
        xy.append(pix + rng.normal(0, 0.3, pix.shape))
    obs = Observations(np.array(view), np.array(point), np.vstack(xy))
    R0 = np.array([rotation_about_axis([1, 0, 0], 0.3) @ R for R in Rs])
    R0[0] = Rs[0]
    X0 = points + rng.normal(0, 0.05, points.shape)
    before = np.sqrt(np.mean(reprojection_residuals(R0, ts, X0, obs, K) ** 2))
    R1, t1, X1 = bundle_adjust(R0, ts.copy(), X0, obs, K, fixed_view=0, loss="linear")
    after = np.sqrt(np.mean(reprojection_residuals(R1, t1, X1, obs, K) ** 2))
    assert before > 3.0 and after < 0.35
    np.testing.assert_allclose(R1[0], Rs[0])
    # scipy's least_squares on the same problem reaches the same cameras and points (up
    # to the free scale, which both leave near where it started).
    Rs_, ts_, Xs_ = scipy_bundle_adjust(R0, ts.copy(), X0, obs, K, fixed_view=0,
                                        loss="linear", scale_px=1.0, max_evaluations=500)
    ours = np.sqrt(np.mean(reprojection_residuals(R1, t1, X1, obs, K) ** 2))
    theirs = np.sqrt(np.mean(reprojection_residuals(Rs_, ts_, Xs_, obs, K) ** 2))
    assert ours <= theirs * (1 + 1e-6)
    scale = np.linalg.norm(ts_[1:]) / np.linalg.norm(t1[1:])
    np.testing.assert_allclose(R1, Rs_, atol=1e-6)
    np.testing.assert_allclose(t1 * scale, ts_, atol=1e-5 * np.linalg.norm(ts_))


def test_schur_product_sparse_equals_dense():
    rng = np.random.default_rng(1)
    camera, point = [], []
    for p in range(400):  # tracks of 2-6 views among 30 cameras
        views = rng.choice(30, rng.integers(2, 7), replace=False)
        camera += list(views)
        point += [p] * len(views)
    camera, point = np.array(camera), np.array(point)
    shuffle = rng.permutation(len(camera))
    camera, point = camera[shuffle], point[shuffle]
    # As in the Schur complement: Y = W V^-1 with one symmetric V per point.
    A = rng.normal(size=(400, 3, 3))
    V_inv = A @ A.transpose(0, 2, 1) + np.eye(3)
    W = rng.normal(size=(len(camera), 6, 3))
    Y = W @ V_inv[point]
    dense = schur_product_dense(Y, W, camera, point, 30)
    np.testing.assert_allclose(schur_product_sparse(Y, W, camera, point, 30), dense,
                               atol=1e-10)
    # Points a chunk at a time (tables of at most 30 x 7 entries): the same sum.
    np.testing.assert_allclose(schur_product_sparse(Y, W, camera, point, 30, chunk_entries=210),
                               dense, atol=1e-10)
    # Point numbers with gaps and cameras that see nothing (30 and 31) change nothing.
    wider = schur_product_sparse(Y, W, camera, 3 * point + 1, 32)
    np.testing.assert_allclose(wider[:180, :180], dense, atol=1e-10)
    assert not wider[180:].any() and not wider[:, 180:].any()
    # One point's contribution by hand: camera blocks (a, b) get Y_a W_b^T.
    obs = np.flatnonzero(point == 7)
    S = schur_product_sparse(Y[obs], W[obs], camera[obs], point[obs], 30)
    a, b = obs[0], obs[1]
    np.testing.assert_allclose(S[6 * camera[a]:6 * camera[a] + 6, 6 * camera[b]:6 * camera[b] + 6],
                               Y[a] @ W[b].T)


def test_check_names_a_view_whose_pose_contradicts_its_pairs():
    """Break a correct model on purpose: one camera turned by 3 deg, then half the cameras
    mirrored through a plane (a fold); the check must name them, and pass the intact one."""
    features, pairs, Rs, ts, _ = _synthetic_views(noise_px=0.3)
    registered = np.ones(len(Rs), dtype=bool)
    intact = check_model(registered, Rs, ts, pairs, features, K, 4.0, reference=0)
    assert intact.ok and intact.pairs_checked == len(pairs) and not intact.inconsistent_pairs
    turned = Rs.copy()
    turned[3] = rotation_about_axis([0.3, 1.0, 0.2], 3.0) @ Rs[3]
    broken = check_model(registered, turned, ts, pairs, features, K, 4.0, reference=0)
    assert broken.suspect_views == (3,) and not broken.ok
    assert {(i, j) for i, j, _ in broken.inconsistent_pairs} == {
        (min(3, v), max(3, v)) for v in range(len(Rs)) if v != 3}
    # A fold: the last views placed as if the scene were mirrored through x = 0 (centres
    # and orientations reflected): consistent among themselves, not with the others.
    def folded(views):
        M = np.diag([-1.0, 1.0, 1.0])
        R_, t_ = Rs.copy(), ts.copy()
        for v in views:
            R_[v] = M @ Rs[v] @ M
            t_[v] = -R_[v] @ (M @ (-Rs[v].T @ ts[v]))
        return check_model(registered, R_, t_, pairs, features, K, 4.0, reference=0)

    assert folded((4, 5)).suspect_views == (4, 5)
    assert not folded((3, 4, 5)).ok  # half and half: which half is right cannot be told


def test_similarity_and_quaternions():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(10, 3))
    R = rotation_about_axis([1, 2, 3], 40)
    dst = 2.5 * src @ R.T + np.array([1.0, -2.0, 0.5])
    s, A, b = similarity_transform(src, dst)
    assert s == pytest.approx(2.5) and np.allclose(A, R) and np.allclose(b, [1, -2, 0.5])
    for axis, angle in (([1, 0, 0], 179.0), ([0, 1, 1], 30.0), ([1, 1, 0], -120.0)):
        Q = rotation_about_axis(axis, angle)
        q = quaternion_from_rotation(Q)
        assert q[0] >= 0 and np.allclose(rotation_from_quaternion(q), Q)


# -- real data -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fountain_views(fountain, tmp_path_factory):
    """reconstruct-views on all 11 fountain images at half resolution (1536 px)."""
    out = tmp_path_factory.mktemp("views")
    proc = subprocess.run(
        [sys.executable, "-m", "scene3D", "reconstruct-views", str(fountain / "images"),
         "--calib", str(REPO / "data" / "fountain_P11_intrinsics.yaml"),
         "--ground-truth", str(fountain / "gt_dense_cameras"), "--out", str(out),
         "--export", "nerfstudio"],
        capture_output=True, text=True, timeout=900)
    return proc, out


def test_fountain_all_views_against_ground_truth(fountain_views):
    proc, out = fountain_views
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["registered"] == 11 and summary["unregistered"] == []
    assert summary["focal_refits"] == [] and summary["warnings"] == []  # the calibration fits
    assert summary["image_size"] == [1536, 1024]
    assert summary["reprojection_rmse_px"] < 1.0
    gt = summary["ground_truth"]
    assert gt["max_center_error_fraction"] < 0.02
    assert gt["max_rotation_error_deg"] < 0.5
    assert summary["points"] > 3000 and summary["mean_track_length"] > 2.5
    assert "registered view" in proc.stderr  # progress per view
    # Every stage timed (tracks were built but counted as 0 s), none beyond the total.
    timings = summary["timings_s"]
    stages = {k: v for k, v in timings.items() if k != "total"}
    assert all(v > 0 for v in stages.values()), stages
    assert sum(stages.values()) <= timings["total"]


def test_colmap_model_is_consistent(fountain_views):
    """Parse the COLMAP text files and reproject points with the stored poses."""
    _, out = fountain_views
    cam_line = [line for line in (out / "colmap" / "cameras.txt").read_text().splitlines()
                if not line.startswith("#")][0].split()
    assert cam_line[1] == "PINHOLE"
    fx, fy, cx, cy = map(float, cam_line[4:8])
    lines = [line for line in (out / "colmap" / "images.txt").read_text().splitlines()
             if not line.startswith("#")]
    images = {}
    for header, pts in zip(lines[0::2], lines[1::2]):
        h = header.split()
        R = rotation_from_quaternion(list(map(float, h[1:5])))
        t = np.array(list(map(float, h[5:8])))
        xy = np.array(pts.split(), float).reshape(-1, 3)
        images[int(h[0])] = (R, t, xy)
    assert len(images) == 11
    checked = 0
    for line in [line for line in (out / "colmap" / "points3D.txt").read_text().splitlines()
                 if not line.startswith("#")][:200]:
        v = line.split()
        X = np.array(list(map(float, v[1:4])))
        track = np.array(v[8:], int).reshape(-1, 2)
        for image_id, idx in track:
            R, t, xy = images[image_id]
            assert int(xy[idx, 2]) == int(v[0])  # the 2D point refers back to this 3D point
            c = R @ X + t
            u = np.array([fx * c[0] / c[2] + cx, fy * c[1] / c[2] + cy])
            assert np.linalg.norm(u - xy[idx, :2]) < 6.0  # 3 px in the working images
            checked += 1
    assert checked > 300


def test_the_nerfstudio_export_has_the_cameras_of_the_ground_truth(fountain, fountain_views):
    """transforms.json: the photos' intrinsics at the top, each frame's file_path leading
    to its photo, camera-to-world in OpenGL axes that match the Strecha cameras after a
    similarity as the model's do."""
    from scene3D.io.datasets import read_strecha_camera

    proc, out = fountain_views
    assert f"Wrote '{out / 'transforms.json'}'" in proc.stdout
    data = json.loads((out / "transforms.json").read_text())
    summary = json.loads((out / "reconstruction.json").read_text())
    K_work = np.array(summary["K"])
    assert (data["w"], data["h"], data["camera_model"]) == (3072, 2048, "OPENCV")
    assert data["fl_x"] == pytest.approx(2 * K_work[0, 0])
    assert data["cx"] == pytest.approx(2 * (K_work[0, 2] + 0.5))
    assert data["ply_file_path"] == "points.ply"
    R, C, truth = [], [], []
    for frame in data["frames"]:
        photo = (out / frame["file_path"]).resolve()
        assert photo == (fountain / "images" / photo.name).resolve()
        c2w = np.array(frame["transform_matrix"])
        R.append((c2w[:3, :3] @ np.diag([1.0, -1.0, -1.0])).T)
        C.append(c2w[:3, 3])
        truth.append(read_strecha_camera(fountain / "gt_dense_cameras"
                                         / f"{photo.name}.camera"))
    assert len(R) == 11
    err = camera_set_error(np.array(R), np.array(C), np.array([c.R for c in truth]),
                           np.array([c.center for c in truth]))
    assert err.center_errors.max() < 0.02 and err.rotation_errors_deg.max() < 0.5


def test_pycolmap_reads_the_model(fountain_views):
    pycolmap = pytest.importorskip("pycolmap")
    _, out = fountain_views
    model = pycolmap.Reconstruction(str(out / "colmap"))
    assert model.num_reg_images() == 11 and model.num_points3D() > 3000


def test_the_colmap_model_is_of_the_photos_as_they_are(fountain, fountain_views):
    """The cameras are at the photos' size (3072x2048, not the working 1536x1024), with K
    scaled back; pycolmap opens the photos at that size and its reprojection errors,
    recomputed with its own camera model, are ours (the working images' errors doubled)."""
    pycolmap = pytest.importorskip("pycolmap")
    _, out = fountain_views
    summary = json.loads((out / "reconstruction.json").read_text())
    rec = pycolmap.Reconstruction(str(out / "colmap"))
    (camera,) = rec.cameras.values()
    K_work = np.array(summary["K"])
    assert (camera.width, camera.height) == (3072, 2048)
    np.testing.assert_allclose(camera.calibration_matrix(),
                               [[2 * K_work[0, 0], 0, 2 * (K_work[0, 2] + 0.5)],
                                [0, 2 * K_work[1, 1], 2 * (K_work[1, 2] + 0.5)], [0, 0, 1]],
                               rtol=1e-9)
    for image in rec.images.values():
        photo = cv2.imread(str(fountain / "images" / image.name), cv2.IMREAD_UNCHANGED)
        assert photo.shape[:2] == (camera.height, camera.width)
    residuals = []
    for image in rec.images.values():
        for p2d in image.points2D:
            if p2d.has_point3D():
                xy = image.project_point(rec.points3D[p2d.point3D_id].xyz)
                residuals.append(xy - p2d.xy)
    residuals = np.array(residuals)
    rmse = np.sqrt(np.mean(residuals**2))
    assert rmse == pytest.approx(2 * summary["reprojection_rmse_px"], rel=1e-5)
    stored = {pid: p.error for pid, p in rec.points3D.items()}
    rec.update_point_3d_errors()
    recomputed = np.array([rec.points3D[pid].error for pid in stored])
    np.testing.assert_allclose(recomputed, list(stored.values()), atol=1e-5)
    cameras = json.loads((out / "cameras.json").read_text())
    assert sorted(cameras) == sorted(image.name for image in rec.images.values())
    for cam in cameras.values():
        assert cam["image_size"] == [3072, 2048] and cam["camera_model"] == "PINHOLE"
        np.testing.assert_allclose(cam["K"], camera.calibration_matrix() - [[0, 0, 0.5],
                                                                            [0, 0, 0.5],
                                                                            [0, 0, 0]])


def test_an_unrelated_or_blank_image_is_reported_not_registered(fountain, chessboards, tmp_path):
    """Also: the book's SURF asked for, the JSON records the detector that ran."""
    from scene3D.features import matching as features

    folder = tmp_path / "mixed"
    folder.mkdir()
    for i in (3, 4, 5, 6):
        shutil.copy(fountain / "images" / f"{i:04d}.jpg", folder / f"{i:04d}.jpg")
    board = cv2.imread(str(chessboards / "opencv-left" / "left01.jpg"))
    cv2.imwrite(str(folder / "0005b_board.jpg"), cv2.resize(board, (3072, 2048)))
    cv2.imwrite(str(folder / "0006b_blank.jpg"), np.full((2048, 3072, 3), 128, np.uint8))
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "scene3D", "reconstruct-views", str(folder), "--calib",
         str(REPO / "data" / "fountain_P11_intrinsics.yaml"), "--max-width", "800",
         "--no-plots", "--feature", "surf", "--out", str(out)],
        capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["feature_requested"] == "surf"
    assert summary["feature"] == ("SURF" if features.surf_available() else "SIFT")
    assert proc.stderr.count("SURF is patented") == (0 if features.surf_available() else 1)
    # A blank photo has no keypoints at all: it is left out like any other.
    assert sorted(summary["unregistered"]) == ["0005b_board.jpg", "0006b_blank.jpg"]
    assert all(summary["unregistered_reasons"][name] for name in summary["unregistered"])
    assert summary["registered"] == 4 and len(summary["models"]) == 1
    # Neither shares a verified pair with another view: that is the reason, said once.
    assert {summary["unregistered_reasons"][name] for name in summary["unregistered"]} == {
        "no verified pair with any other view: does it overlap the others?"}
    assert ("views '0005b_board.jpg', '0006b_blank.jpg' could not be registered: no verified "
            "pair with any other view") in proc.stderr


def test_reconstruct_views_bad_input(tmp_path, fountain):
    base = [sys.executable, "-m", "scene3D", "reconstruct-views"]
    calib = str(REPO / "data" / "fountain_P11_intrinsics.yaml")
    one = subprocess.run(base + [str(fountain / "images" / "0004.jpg"), "--calib", calib,
                                 "--out", str(tmp_path)], capture_output=True, text=True)
    assert one.returncode == 2 and "at least two images" in one.stderr
    missing = subprocess.run(base + [str(tmp_path / "*.jpg"), "--calib", calib],
                             capture_output=True, text=True)
    assert missing.returncode == 2 and "no image matches" in missing.stderr
    # A folder and one of its files: that view would be paired with itself.
    twice = subprocess.run(base + [str(fountain / "images"), str(fountain / "images" / "0004.jpg"),
                                   "--calib", calib, "--out", str(tmp_path)],
                           capture_output=True, text=True)
    assert twice.returncode == 2 and "image given twice" in twice.stderr
    assert len(twice.stderr.strip().splitlines()) == 1


def test_sequential_pairs_through_the_api(fountain):
    from scene3D import reconstruct_views
    from scene3D.io.datasets import read_strecha_camera

    cams = [read_strecha_camera(fountain / "gt_dense_cameras" / f"{i:04d}.jpg.camera")
            for i in range(2, 7)]
    paths = [fountain / "images" / f"{i:04d}.jpg" for i in range(2, 7)]
    messages = []
    recon = reconstruct_views(paths, cams[0].K, np.zeros(5), max_width=800,
                              pairs="sequential", settings=SfMSettings(neighbours=1),
                              progress=messages.append)
    assert recon.pair_selection == "sequential (1 following views)"
    assert recon.registered.all() and recon.names[0] == "0002.jpg"
    assert recon.image_size == (768, 512)
    err = camera_set_error(recon.R, recon.centers, np.array([c.R for c in cams]),
                           np.array([c.center for c in cams]))
    assert err.center_errors.max() < 0.02 and err.rotation_errors_deg.max() < 0.5
    assert any("registered view" in m for m in messages)


def test_a_calibration_that_does_not_fit_stops_with_the_reason(fountain):
    from scene3D import reconstruct_views
    from scene3D.io.datasets import read_strecha_camera

    K = read_strecha_camera(fountain / "gt_dense_cameras" / "0003.jpg.camera").K.copy()
    K[:2, :2] *= 0.8  # a calibration for another zoom
    paths = [fountain / "images" / f"{i:04d}.jpg" for i in range(3, 6)]
    with pytest.raises(ReconstructionError, match="focal length 1.2") as info:
        reconstruct_views(paths, K, np.zeros(5), max_width=800)
    assert info.value.reason == "no_initial_pair"



def test_one_photo_twice_stops_with_what_to_check(fountain, tmp_path):
    from scene3D import reconstruct_views
    from scene3D.io.datasets import read_strecha_camera

    K = read_strecha_camera(fountain / "gt_dense_cameras" / "0004.jpg.camera").K
    copy = tmp_path / "copy.jpg"
    copy.write_bytes((fountain / "images" / "0004.jpg").read_bytes())
    original = fountain / "images" / "0004.jpg"
    with pytest.raises(ValueError, match=re.escape(f"'{copy}' and '{original}' are the same "
                                                   "photo")):  # by path, as the sizes' error
        reconstruct_views([original, copy], K, np.zeros(5), max_width=800)
    # Saved again (other pixels, the same view): no start from a pair without a baseline.
    img = cv2.imread(str(fountain / "images" / "0004.jpg"))
    cv2.imwrite(str(copy), img, [cv2.IMWRITE_JPEG_QUALITY, 80])
    with pytest.raises(ReconstructionError, match="no pair of views gives a trustworthy "
                                                  "two-view start") as info:
        reconstruct_views([fountain / "images" / "0004.jpg", copy], K, np.zeros(5),
                          max_width=800)
    assert info.value.reason == "no_initial_pair"

def _cli(args, tmp_path, name="out"):
    out = tmp_path / name
    proc = subprocess.run([sys.executable, "-m", "scene3D", "reconstruct-views", *args,
                           "--calib", str(REPO / "data" / "fountain_P11_intrinsics.yaml"),
                           "--max-width", "800", "--no-plots", "--out", str(out)],
                          capture_output=True, text=True, timeout=900)
    return proc, out


def test_shuffled_names_give_the_same_reconstruction(fountain, tmp_path):
    """The fountain images under random names, in random order (symlinks): the same
    cameras, bit for bit up to float noise, as under their own names."""
    images = sorted((fountain / "images").glob("*.jpg"))[2:9]
    ordered = tmp_path / "ordered"
    ordered.mkdir()
    for p in images:
        (ordered / p.name).symlink_to(p)
    shuffled = tmp_path / "shuffled"
    shuffled.mkdir()
    rng = np.random.default_rng(7)
    alias = {}
    for p in rng.permutation(images):
        alias[p.name] = f"{rng.integers(10**8):08d}.jpg"
        (shuffled / alias[p.name]).symlink_to(p)
    a_proc, a_out = _cli([str(ordered), "--pairs", "retrieval", "--retrieval-neighbours", "3"],
                         tmp_path, "a")
    b_proc, b_out = _cli([str(shuffled), "--pairs", "retrieval", "--retrieval-neighbours",
                          "3"], tmp_path, "b")
    assert a_proc.returncode == 0, a_proc.stderr
    assert b_proc.returncode == 0, b_proc.stderr
    cams_a = json.loads((a_out / "cameras.json").read_text())
    cams_b = json.loads((b_out / "cameras.json").read_text())
    assert len(cams_a) == len(images) == len(cams_b)
    for name, cam in cams_a.items():
        other = cams_b[alias[name]]
        np.testing.assert_allclose(cam["R"], other["R"], atol=1e-6)
        np.testing.assert_allclose(cam["center"], other["center"], atol=1e-6)


def test_unconnected_scenes_become_two_models(fountain, data_root, tmp_path):
    """Five fountain views and four Herz-Jesus views: no pair joins the two scenes, so each
    is a model of its own, written to its own folder, and the summary says which is where."""
    folder = tmp_path / "two"
    folder.mkdir()
    for i in range(2, 7):
        (folder / f"f{i}.jpg").symlink_to(fountain / "images" / f"{i:04d}.jpg")
    for i in range(0, 4):
        (folder / f"h{i}.jpg").symlink_to(data_root / "Herz-Jesus-P8" / "images" / f"{i:04d}.jpg")
    truth = tmp_path / "truth"
    truth.mkdir()
    for link in folder.iterdir():
        scene, i = ("fountain-P11", link.stem[1:]) if link.stem[0] == "f" else \
            ("Herz-Jesus-P8", link.stem[1:])
        (truth / f"{link.name}.camera").symlink_to(
            data_root / scene / "gt_dense_cameras" / f"{int(i):04d}.jpg.camera")
    proc, out = _cli([str(folder), "--ground-truth", str(truth)], tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "reconstruction.json").read_text())
    assert len(summary["models"]) == 2 and summary["unregistered"] == []
    views = [sorted(m["views"]) for m in summary["models"]]
    assert views == [[f"f{i}.jpg" for i in range(2, 7)], [f"h{i}.jpg" for i in range(4)]]
    assert summary["models"][1]["folder"] == "model-1"
    assert (out / "model-1" / "points.ply").is_file() and (out / "points.ply").is_file()
    assert json.loads((out / "model-1" / "cameras.json").read_text()).keys() == {
        f"h{i}.jpg" for i in range(4)}
    assert "model 1 (model-1/): 4 more views" in proc.stdout
    assert proc.stdout.startswith("9 of 9 views registered in 2 models; the largest, 5 views")
    assert "the largest model: f2.jpg, f3.jpg, f4.jpg, f5.jpg, f6.jpg" in proc.stdout
    # Each model against its truth, in a line of its own, and close to it.
    for m, entry in enumerate(summary["models"]):
        who = "the largest model" if m == 0 else "model 1 (model-1/)"
        assert f"{who} against ground truth: camera centres within" in proc.stdout
        assert entry["ground_truth"]["max_rotation_error_deg"] < 0.2
        assert entry["ground_truth"]["max_center_error_fraction"] < 0.005
    # The report tells the same: every view in a model (it said the further model's views
    # "could not be registered"), and no warning.
    page = (out / "report.html").read_text()
    assert ('<div class="verdict ok" id="verdict"><strong>9 of 9 views registered in 2 '
            "models</strong></div>") in page
    views_table = page.split('<table id="views">')[1].split("</table>")[0]
    assert views_table.count("<td>model 1 (model-1/)</td>") == 4
    assert "<td>none: " not in views_table
    assert sorted(summary["files"]) == _files_in(out)
    # Again on the fountain alone into the same folder, without the report: the earlier
    # run's model-1/ and report.html go; a file of the user's there stays.
    (out / "notes.txt").write_text("mine")
    for link in folder.glob("h*.jpg"):
        link.unlink()
    proc, out = _cli([str(folder), "--no-report"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "reconstruction.json").read_text())
    assert len(summary["models"]) == 1
    assert not (out / "model-1").exists() and not (out / "report.html").exists()
    assert f"Removed '{out / 'model-1' / 'points.ply'}'" in proc.stdout
    assert sorted([*summary["files"], "notes.txt"]) == _files_in(out)


def _files_in(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())


def _zoom_factor_quoted(why: str, whose: str) -> float:
    """The factor a reason quotes: 'the candidate pairs to start from fit a focal length
    1.24 times {whose} (the median of 6...)'."""
    quoted = re.search(r"the candidate pairs to start from fit a focal length (\d+\.\d+) "
                       rf"times {re.escape(whose)} \(the median of \d+", why)
    assert quoted, why
    return float(quoted.group(1))


def test_views_that_cannot_start_a_further_model_are_told_why(fountain, data_root, tmp_path):
    """Five fountain views and four Herz-Jesus views zoomed 1.25 times (cropped and resized
    back): under the fountain's calibration the zoomed views' candidate pairs refute its
    focal length, so they form no model. Each is told that, and why (the focal length
    their matches call for, 1.25 times), not a reason left over from the fountain model's
    registration. (Before the candidates' focal checks were weighed for every model,
    which candidate pair was quoted, or whether the zoomed views formed a model of their
    own, was left to the CPU's floating point.)"""
    from scene3D.io.datasets import read_strecha_camera
    from scene3D.multiview import reconstruct_views

    paths = [fountain / "images" / f"{i:04d}.jpg" for i in range(2, 7)]
    for i in range(4):
        image = cv2.imread(str(data_root / "Herz-Jesus-P8" / "images" / f"{i:04d}.jpg"))
        h, w = image.shape[:2]
        ch, cw = round(h / 1.25), round(w / 1.25)
        crop = image[(h - ch) // 2:(h - ch) // 2 + ch, (w - cw) // 2:(w - cw) // 2 + cw]
        paths.append(tmp_path / f"h{i}.jpg")
        cv2.imwrite(str(paths[-1]), cv2.resize(crop, (w, h), interpolation=cv2.INTER_AREA))
    zoomed = [f"h{i}.jpg" for i in range(4)]
    K = read_strecha_camera(fountain / "gt_dense_cameras" / "0004.jpg.camera").K
    r = reconstruct_views(paths, K, max_width=800)
    assert len(r.models) == 1 and sorted(r.unregistered) == zoomed
    for name in zoomed:
        why = r.unregistered_reasons[name]
        assert why.startswith("not in a model, and no further one could start from the "
                              "4 views left: "), why
        assert 1.15 < _zoom_factor_quoted(why, "the calibration's") < 1.35
        assert why.endswith("; does the calibration fit these photos?"), why
    # Without a calibration the views left start from the fountain model's focal length,
    # and their reason names it as such, not as a calibration's.
    from scene3D.geometry.intrinsics_prior import focal_prior

    r = reconstruct_views(paths, None, max_width=800,
                          focal_prior=focal_prior(None, (3072, 2048)))
    assert len(r.models) == 1 and sorted(r.unregistered) == zoomed
    for name in zoomed:
        why = r.unregistered_reasons[name]
        assert 1.15 < _zoom_factor_quoted(why, "the one the other photos gave") < 1.35
        assert "calibration" not in why, why
        assert why.endswith("are the photos of one still scene, from one camera at one zoom "
                            "setting?"), why


def test_a_broken_reconstruction_is_reported_not_written_as_a_success(fountain, tmp_path,
                                                                       monkeypatch, capsys):
    """Turn one registered camera by 5 deg just before the result is taken (as a wrong
    registration would leave it): the command must say so and exit 1, not 0."""
    from scene3D.cli.multiview import main
    from scene3D.multiview import state

    original = state.GrowingModel.result

    def broken(self, check):
        view = [v for v in np.flatnonzero(self.registered) if v != self.reference][1]
        self.R[view] = rotation_about_axis([0.2, 1.0, 0.1], 5.0) @ self.R[view]
        return original(self, self.check())

    monkeypatch.setattr(state.GrowingModel, "result", broken)
    paths = [str(fountain / "images" / f"{i:04d}.jpg") for i in range(3, 8)]
    out = tmp_path / "out"
    code = main([*paths, "--calib", str(REPO / "data" / "fountain_P11_intrinsics.yaml"),
                 "--max-width", "800", "--no-plots", "--out", str(out), "-q"])
    assert code == 1
    err = capsys.readouterr().err
    assert "failed its consistency check" in err
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["status"] == "failed"
    check = summary["models"][0]["check"]
    assert check["status"] == "failed" and len(check["suspect_views"]) == 1
    assert check["suspect_views"][0] in err


class _PicklingEngine:
    """An engine that sends every task's function, arguments and result through pickle,
    as an engine of worker processes would: what reconstruct_views hands it must survive."""

    name = "pickling"

    def __init__(self):
        self.tasks: dict[str, int] = {}

    def map(self, fn, arguments, *, label="tasks", progress=None):
        import pickle

        for args in arguments:
            fn_, args_ = pickle.loads(pickle.dumps((fn, args)))
            self.tasks[label] = self.tasks.get(label, 0) + 1
            yield pickle.loads(pickle.dumps(fn_(*args_)))

    def share(self, value):
        return value


def test_tasks_run_through_the_engine_and_survive_pickling(fountain):
    from scene3D.engines import LocalEngine
    from scene3D.io.datasets import read_strecha_camera
    from scene3D.multiview import reconstruct_views

    K = read_strecha_camera(fountain / "gt_dense_cameras" / "0003.jpg.camera").K
    paths = [fountain / "images" / f"{i:04d}.jpg" for i in range(3, 7)]
    engine = _PicklingEngine()
    remote = reconstruct_views(paths, K, max_width=800, engine=engine)
    local = reconstruct_views(paths, K, max_width=800, engine=LocalEngine())
    assert engine.tasks["features"] == 4 and engine.tasks["pairs"] == 6
    assert remote.registered.all() and local.registered.all()
    np.testing.assert_allclose(remote.R, local.R, atol=1e-9)
    np.testing.assert_allclose(remote.t, local.t, atol=1e-9)


class _WithholdingEngine:
    """The in-process engine, except that every pair of one image in the first round of
    verification comes back unverified (as if its most similar views had all been wrong
    candidates); pairs matched later, when a view is retried, are verified as usual."""

    name = "withholding"

    def __init__(self, image):
        self.image, self.keypoints, self.labels = str(image), None, []

    def map(self, fn, arguments, *, label="tasks", progress=None):
        self.labels.append(label)
        for args in arguments:
            if label == "pairs" and any(np.array_equal(f.keypoints, self.keypoints)
                                        for f in args[:2]):
                yield fn(*args)[0], None  # its putative matches, and no verified pair
                continue
            result = fn(*args)
            if label == "features" and str(args[0]) == self.image:
                self.keypoints = result[0].keypoints
            yield result

    def share(self, value):
        return value


def test_a_view_that_fails_at_first_is_registered_with_further_candidates(fountain):
    """Retrieval pairs (3 most similar views each) with every first-round pair of 0005
    withheld: 0005 has no 2D-3D match when the others are registered, is matched with its
    next most similar views of the model, and registers where the truth puts it. Without
    retries it stays out, with the reason."""
    from scene3D.io.datasets import read_strecha_camera
    from scene3D.multiview import reconstruct_views

    paths = [fountain / "images" / f"{i:04d}.jpg" for i in range(1, 10)]
    cams = [read_strecha_camera(fountain / "gt_dense_cameras" / f"{p.name}.camera")
            for p in paths]
    target = 4  # 0005.jpg
    settings = SfMSettings(retrieval_neighbours=3)
    engine = _WithholdingEngine(paths[target])
    lines = []
    r = reconstruct_views(paths, cams[0].K, max_width=800, pairs="retrieval",
                          settings=settings, engine=engine, progress=lines.append)
    assert "more pairs" in engine.labels
    assert any("further pairs verified" in line for line in lines)
    assert r.registered.all() and r.ok and len(r.models) == 1
    err = camera_set_error(r.R, r.centers, np.array([c.R for c in cams]),
                           np.array([c.center for c in cams]))
    assert err.rotation_errors_deg[target] < 0.3 and err.center_errors[target] < 0.01

    engine = _WithholdingEngine(paths[target])
    stuck = reconstruct_views(paths, cams[0].K, max_width=800, pairs="retrieval",
                              settings=dataclasses.replace(settings, retry_rounds=0),
                              engine=engine)
    assert "more pairs" not in engine.labels
    assert stuck.unregistered == ("0005.jpg",)
    # Its pairs withheld and no retry: no verified pair at all, which is what it is told.
    assert stuck.unregistered_reasons["0005.jpg"].startswith("no verified pair with any other")


def test_ground_truth_is_read_and_checked_before_the_reconstruction(fountain, tmp_path, capsys,
                                                                    monkeypatch):
    """A broken or missing camera file stops the command at once (exit 2, the file named),
    not after the whole reconstruction."""
    from scene3D.cli import multiview

    from .test_datasets import camera_text

    monkeypatch.setattr(multiview, "reconstruct_views", lambda *a, **k: pytest.fail(
        "the reconstruction ran before the ground truth was checked"))
    gt = tmp_path / "gt"
    gt.mkdir()
    (gt / "0004.jpg.camera").write_text(camera_text(fountain, {8: "inf inf"}))
    images = [str(fountain / "images" / f"000{i}.jpg") for i in (4, 5)]
    argv = [*images, "--calib", str(REPO / "data" / "fountain_P11_intrinsics.yaml"),
            "--ground-truth", str(gt), "--out", str(tmp_path / "out")]
    assert multiview.main(argv) == 2
    err = capsys.readouterr().err
    assert err == (f"error: camera file '{gt / '0004.jpg.camera'}': the image size must be "
                   "two positive whole numbers, got inf inf\n")
    (gt / "0004.jpg.camera").write_text(camera_text(fountain, {5: "nan nan nan"}))
    assert multiview.main(argv) == 2
    assert "0004.jpg.camera': R contains non-finite values" in capsys.readouterr().err
    (gt / "0004.jpg.camera").write_text(camera_text(fountain, {}))
    assert multiview.main(argv) == 2
    assert capsys.readouterr().err == (f"error: --ground-truth '{gt}' has no camera file for "
                                       f"'0005.jpg' (expected '{gt / '0005.jpg.camera'}')\n")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case", ["tiny", "blank", "max-width 16"])
def test_images_without_keypoints_end_with_the_reason(fountain, tmp_path, capsys, case):
    """No view has keypoints (10x10 px, black, or fountain at 12x8 px): no start, exit 1,
    and the line says the images have too few keypoints."""
    from scene3D.cli.multiview import main

    if case == "max-width 16":
        images = [str(fountain / "images" / f"000{i}.jpg") for i in (4, 5)]
        extra = ["--calib", str(REPO / "data" / "fountain_P11_intrinsics.yaml"),
                 "--max-width", "16"]
    else:
        rng = np.random.default_rng(1)
        images = []
        for i in range(2):
            img = (rng.integers(0, 256, (10, 10, 3)) if case == "tiny"
                   else np.zeros((200, 300, 3))).astype(np.uint8)
            images.append(str(tmp_path / f"{case}{i}.png"))
            cv2.imwrite(images[-1], img)
        extra = []
    assert main([*images, *extra, "--no-plots", "--out", str(tmp_path / "out"), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: too few keypoints to match: 0 in '{images[0]}', ")
    assert "where a pair needs 30; are the images blank, blurred or tiny?" in err
    assert len(err.strip().splitlines()) == 1


def test_a_model_without_points_is_a_failure(fountain, tmp_path, monkeypatch, capsys):
    """Two registered views and no point (as a calibration that does not fit can leave
    them): exit 1, status 'failed', the reason on stderr; not a success."""
    from scene3D.cli.multiview import main
    from scene3D.multiview import state

    original = state.GrowingModel.result

    def without_points(self, check):
        return dataclasses.replace(
            original(self, check), points3d=np.zeros((0, 3)), colors=np.zeros((0, 3), np.uint8),
            observations=Observations(np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2))),
            reprojection_rmse_px=float("nan"))

    monkeypatch.setattr(state.GrowingModel, "result", without_points)
    out = tmp_path / "out"
    code = main([str(fountain / "images" / f"000{i}.jpg") for i in (4, 5)]
                + ["--calib", str(REPO / "data" / "fountain_P11_intrinsics.yaml"),
                   "--max-width", "400", "--no-plots", "--no-report", "--out", str(out), "-q"])
    assert code == 1
    err = capsys.readouterr().err
    assert err == ("error: the largest model has 0 points for its 2 views, fewer than 10: its "
                   "cameras rest on nothing (does the calibration fit these photos?); see "
                   "reconstruction.json, the files are written for inspection only\n")
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["status"] == "failed" and summary["points"] == 0
    assert summary["models"][0]["status"] == "failed"
    assert summary["models"][0]["check"]["status"] == "ok"  # consistent, but empty


def test_the_library_calls_a_model_without_points_a_failure_as_the_command_does(
        fountain, tmp_path, monkeypatch):
    """The same two views without points in Python: ``ok`` is False (the command's exit 1),
    the check itself passed, the summary says 'failed', and the model's folder holds its
    files (scene3D.io.model_folder)."""
    from scene3D.io.calibration import load_calibration
    from scene3D.io.export import read_ply
    from scene3D.io.model_folder import MODEL_FILES, write_model
    from scene3D.multiview import reconstruct_views, state

    original = state.GrowingModel.result

    def without_points(self, check):
        return dataclasses.replace(
            original(self, check), points3d=np.zeros((0, 3)), colors=np.zeros((0, 3), np.uint8),
            observations=Observations(np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2))),
            reprojection_rmse_px=float("nan"))

    monkeypatch.setattr(state.GrowingModel, "result", without_points)
    camera = load_calibration(REPO / "data" / "fountain_P11_intrinsics.yaml")
    recon = reconstruct_views([fountain / "images" / f"000{i}.jpg" for i in (4, 5)],
                              camera.K, camera.dist, max_width=400)
    assert recon.consistent and recon.thin_models == (0,) and not recon.ok
    assert recon.min_model_points == SfMSettings().min_model_points == 10
    summary = recon.to_dict()
    assert summary["status"] == "failed" and summary["points"] == 0
    assert summary["models"][0]["status"] == "failed"
    assert summary["models"][0]["check"]["status"] == "ok"
    written = write_model(tmp_path / "model", recon, recon.main, figure=False)
    assert [p.relative_to(tmp_path / "model").as_posix() for p in written] == list(MODEL_FILES)
    assert len(read_ply(written[0])[0]) == 0


def test_a_copy_of_a_photo_under_another_name_is_refused(fountain, tmp_path):
    """A byte-identical copy is one view twice (chapter4.py and calibrate refuse it too)."""
    folder = tmp_path / "photos"
    folder.mkdir()
    for name in ("0003.jpg", "0004.jpg"):
        shutil.copy(fountain / "images" / name, folder / name)
    shutil.copy(fountain / "images" / "0004.jpg", folder / "0004 copy.jpg")
    proc = subprocess.run(
        [sys.executable, "-m", "scene3D", "reconstruct-views", str(folder), "--calib",
         str(REPO / "data" / "fountain_P11_intrinsics.yaml"), "--max-width", "400",
         "--no-report", "--out", str(tmp_path / "out")], capture_output=True, text=True,
        timeout=300)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1] == (
        f"error: '{folder / '0004.jpg'}' and '{folder / '0004 copy.jpg'}' are the same photo "
        "(the same keypoints): a view cannot pair with itself")
    assert "Traceback" not in proc.stderr
