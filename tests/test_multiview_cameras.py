"""Photos of several cameras in one reconstruction (scene3D.multiview.cameras): grouping
into cameras, the per-camera adjustment, the focal search, and reconstructions of
rendered and real views taken by cameras of different sizes and focal lengths."""

import re
import subprocess
import sys

import cv2
import numpy as np
import pytest

from scene3D.evaluation import camera_set_error
from scene3D.evaluation.camera_variants import FOUR_CAMERAS, write_camera_variants
from scene3D.evaluation.synthetic import lens_photo, orbit_poses, orbit_scene, render_planes
from scene3D.geometry.intrinsics_prior import ExifCamera, camera_groups, camera_priors
from scene3D.geometry.lens import distort_pixels
from scene3D.io.colmap import read_colmap_text
from scene3D.io.datasets import read_strecha_scene
from scene3D.multiview import reconstruct_views
from scene3D.multiview.cameras import (
    corner_change_px,
    pnp_focal_search,
    to_reference_pixels,
)
from scene3D.multiview.settings import SfMSettings
from scene3D.optim.bundle import Observations
from scene3D.optim.bundle_radial import bundle_adjust_cameras
from scene3D.report import (
    multi_view_layers,
    multi_view_report,
    prepare_view,
    reconstruction_report,
)
from scene3D.report.sections import jsonable

CANON = ExifCamera(make="Canon", model="EOS 5D", focal_length_mm=35.0)
CANON_ZOOMED = ExifCamera(make="Canon", model="EOS 5D", focal_length_mm=50.0)
PHONE = ExifCamera(make="Apple", model="iPhone 12", focal_length_35mm=26.0)


def test_photos_are_grouped_into_cameras_as_colmap_groups_them():
    """One camera per size, EXIF make and model and focal length; a photo without EXIF
    joins the first camera of its size; without EXIF, each size its own camera."""
    photos = [("a", CANON, (3000, 2000)), ("b", PHONE, (3000, 2000)),
              ("c", CANON_ZOOMED, (3000, 2000)), ("d", CANON, (3000, 2000)),
              ("e", None, (3000, 2000)), ("f", None, (1000, 800)), ("g", CANON, (1500, 1000))]
    assert camera_groups(photos).tolist() == [0, 1, 2, 0, 0, 3, 4]
    assert camera_groups(photos, "single").tolist() == [0] * 7
    assert camera_groups(photos, "per_photo").tolist() == list(range(7))
    with pytest.raises(ValueError, match="camera mode 'any' is not one of auto, single"):
        camera_groups(photos, "any")
    view_camera, priors = camera_priors(photos[:2] + photos[5:6])
    assert view_camera.tolist() == [0, 1, 2]
    assert [p.image_size for p in priors] == [(3000, 2000), (3000, 2000), (1000, 800)]
    assert priors[2].source == "prior" and priors[2].focal_px == pytest.approx(1200.0)
    with pytest.raises(ValueError, match="one camera is needed"):
        camera_priors(photos[:2], "single")
    # A photo that records less joins a camera all of whose photos it fits, whatever the
    # order: never a camera of two EXIF cameras (which camera_prior would refuse).
    no_focal = ExifCamera(make="Canon", model="EOS 5D")
    size = (3000, 2000)
    for mixed in ([("a", None, size), ("b", CANON, size), ("c", PHONE, size)],
                  [("a", no_focal, size), ("b", CANON, size), ("c", CANON_ZOOMED, size)]):
        assert camera_groups(mixed).tolist() == [0, 0, 1]
        assert len(camera_priors(mixed)[1]) == 2


def test_reference_pixels_are_the_same_rays():
    """A pixel of one pinhole camera taken to another's pixels lies on the same ray."""
    K_a = np.array([[800.0, 0, 320.0], [0, 800.0, 240.0], [0, 0, 1]])
    K_b = np.array([[1500.0, 0, 999.5], [0, 1500.0, 700.0], [0, 0, 1]])
    rays = np.array([[0.1, -0.2, 1.0], [-0.3, 0.05, 1.0]])
    xy_a, xy_b = (rays @ K_a.T)[:, :2], (rays @ K_b.T)[:, :2]
    np.testing.assert_allclose(to_reference_pixels(xy_a, K_a, K_b), xy_b, atol=1e-9)
    assert corner_change_px(K_a, [], K_a, [], (640, 480)) == 0.0
    # A focal length 1 % longer moves the corners' rays 1 % of their radius, in its pixels.
    longer = K_a @ np.diag([1.01, 1.01, 1.0])
    radius = np.hypot(320.0, 240.0)
    assert corner_change_px(K_a, [], longer, [], (641, 481)) == pytest.approx(
        radius * 0.01, rel=1e-9)


def _views(seed=0):
    """Eight views of random points, alternately of two cameras."""
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(-2, 2, 400), rng.uniform(-1.5, 1.5, 400),
                         rng.uniform(5, 9, 400)])
    Rs, ts = [], []
    for v in range(8):
        angle = np.deg2rad(4.0 * v - 14.0)
        R = cv2.Rodrigues(np.array([0.02 * v, angle, 0.0]))[0]
        C = np.array([2.0 * np.sin(angle), 0.1 * v, 7.0 * (1 - np.cos(angle))])
        Rs.append(R)
        ts.append(-R @ C)
    return X, np.array(Rs), np.array(ts)


def test_every_camera_is_adjusted_with_its_own_focal_length_and_lens():
    """Noise-free views of two distorting cameras, both started 5 % off in focal length and
    with no distortion: each camera's f and k1 come back to 1e-6."""
    X, Rs, ts = _views()
    K_true = np.array([[[700.0, 0, 320], [0, 700.0, 240], [0, 0, 1]],
                       [[1100.0, 0, 500], [0, 1100.0, 375], [0, 0, 1]]])
    k_true = np.array([[-0.08], [0.05]])
    view_camera = np.arange(8) % 2
    views, points, xy = [], [], []
    for v in range(8):
        cam = (Rs[v] @ X.T).T + ts[v]
        K = K_true[view_camera[v]]
        pix = (cam / cam[:, 2:]) @ K.T
        views.append(np.full(len(X), v))
        points.append(np.arange(len(X)))
        xy.append(distort_pixels(pix[:, :2], K, k_true[view_camera[v]]))
    obs = Observations(np.concatenate(views), np.concatenate(points), np.concatenate(xy))
    K_start = K_true @ np.diag([1.05, 1.05, 1.0])
    fit = bundle_adjust_cameras(Rs, ts, X, obs, K_start, np.zeros((2, 1)), view_camera, 0,
                                K_start[:, 0, 0], [0.5, 0.5])
    # The gauge is one camera and the data's scale: the focal lengths are determined.
    np.testing.assert_allclose(fit.K[:, 0, 0], K_true[:, 0, 0], rtol=1e-6)
    np.testing.assert_allclose(fit.k, k_true, atol=1e-6)
    assert fit.sigma.shape == (2, 2) and np.all(fit.sigma > 0)


def test_a_cameras_focal_length_is_found_from_one_views_2d_3d_matches():
    """Exact 2D-3D matches of a camera 30 % longer than the guess: the search finds the
    factor to 0.5 %, and 1 when the guess is right."""
    X, Rs, ts = _views(1)
    K_guess = np.array([[800.0, 0, 320], [0, 800.0, 240], [0, 0, 1]])
    for factor in (1.3, 1.0, 0.7):
        K = K_guess @ np.diag([factor, factor, 1.0])
        cam = (Rs[3] @ X.T).T + ts[3]
        xy = ((cam / cam[:, 2:]) @ K.T)[:, :2]
        scale, inliers = pnp_focal_search(X, xy, K_guess, 2.0)
        assert scale == pytest.approx(factor, rel=0.005) and inliers > 300


@pytest.fixture(scope="module")
def two_camera_orbit():
    """Ten views 15 deg apart around the courtyard, alternately by a 512x384 camera of
    f 450 px and a 640x480 camera of f 720 px with barrel distortion (k1 -0.06)."""
    Rs, ts = orbit_poses(24)
    Rs, ts = Rs[:10], ts[:10]
    scene = orbit_scene()
    cameras = [(np.array([[450.0, 0, 255.5], [0, 450.0, 191.5], [0, 0, 1]]), (512, 384), 0.0),
               (np.array([[720.0, 0, 319.5], [0, 720.0, 239.5], [0, 0, 1]]), (640, 480), -0.06)]
    photos = []
    for v, (R, t) in enumerate(zip(Rs, ts)):
        K, size, k1 = cameras[v % 2]
        img = render_planes(K, R, t, size=size, rectangles=scene, supersample=1)[0]
        photos.append(lens_photo(img, K, k1) if k1 else img)
    return photos, Rs, -np.einsum("vji,vj->vi", Rs, ts), cameras


@pytest.fixture(scope="module")
def two_camera_model(two_camera_orbit, tmp_path_factory):
    """The two-camera orbit reconstructed without a calibration, and the folder it saved."""
    photos = two_camera_orbit[0]
    names = [f"{v:02d}.png" for v in range(len(photos))]
    recon = reconstruct_views(photos, None, names=names, progress=lambda _: None)
    folder = tmp_path_factory.mktemp("two_cameras")
    recon.save(folder)
    return recon, names, folder


def test_views_of_two_cameras_register_with_their_own_focal_lengths(two_camera_orbit,
                                                                    two_camera_model):
    """Without a calibration or EXIF the two sizes are two cameras: every view registers,
    each camera's focal length within 0.5 % and k1 within 0.01 of the truth, the cameras
    within 0.1 deg; the observations are each view's own pixels (the model reprojects
    within half a pixel). The COLMAP model (what reconstruct-views writes) has both
    cameras at their sizes, each image naming its own."""
    photos, Rs, centers, cameras = two_camera_orbit
    recon, names, folder = two_camera_model
    assert recon.view_camera.tolist() == [0, 1] * 5 and len(recon.cameras) == 2
    assert recon.main.registered.all()
    for camera, (K, size, k1) in zip(recon.cameras, cameras):
        assert camera.image_size == size and camera.estimated
        assert camera.K[0, 0] == pytest.approx(K[0, 0], rel=0.005)
        assert abs((camera.dist[0] if camera.dist.size else 0.0) - k1) < 0.01
    err = camera_set_error(recon.main.R, recon.main.centers, Rs, centers)
    assert err.rotation_errors_deg.max() < 0.1
    assert recon.reprojection_rmse_px < 0.5
    Ks = recon.view_intrinsics()
    np.testing.assert_array_equal(Ks[1], recon.cameras[1].K)
    # Each point's error with each view's camera, as the working-size COLMAP model has it.
    np.testing.assert_allclose(recon.point_errors_px(),
                               recon.colmap_model(photos=False).point_errors_px(), atol=1e-9)
    assert np.median(recon.point_errors_px()) < 0.5
    summary = recon.to_dict()
    assert [c["image_size"] for c in summary["cameras"]] == [[512, 384], [640, 480]]
    # Five views each: the reference camera is the first of most views, the result's K.
    assert [c["reference"] for c in summary["cameras"]] == [True, False]
    np.testing.assert_array_equal(recon.K, recon.cameras[0].K)
    layers, frusta = multi_view_layers(names, recon.K, recon.image_size, recon.registered,
                                       recon.R, recon.t, recon.points3d, recon.colors)
    page = multi_view_report(names, ["the largest model"] * len(names), jsonable(summary),
                             [], [], {}, prepare_view(layers, frusta)).text()
    assert "The cameras" in page and "Camera 1, the reference camera" in page
    shown = re.search(r"640 x 480 px, focal length ([0-9.]+) px", page)
    assert shown and float(shown.group(1)) == pytest.approx(720.0, rel=0.005)

    model = read_colmap_text(folder / "colmap")
    assert sorted(c.image_size for c in model.cameras.values()) == [(512, 384), (640, 480)]
    for name, camera_id in zip(model.names, model.camera_ids):
        assert model.cameras[int(camera_id)].image_size == cameras[int(name[:2]) % 2][1]
    assert np.median(model.point_errors_px()) < 0.5


def test_the_result_keeps_the_pairs_it_verified_in_the_input_order(two_camera_model):
    """``verified_edges``: ``verified_pairs`` of them, sorted, views ``a < b`` by input index,
    each with at least the inliers a pair needs; neighbours on the orbit (15 deg apart) are
    among them; the report's view graph shows them as inliers."""
    from scene3D.report.diagnostics import verified_inlier_matrix

    recon = two_camera_model[0]
    edges = recon.verified_edges
    assert len(edges) == recon.verified_pairs and list(edges) == sorted(edges)
    assert all(0 <= a < b < len(recon.names) for a, b, _ in edges)
    assert min(n for _, _, n in edges) >= SfMSettings().min_pair_inliers
    assert {(v, v + 1) for v in range(len(recon.names) - 1)} <= {(a, b) for a, b, _ in edges}
    matrix = verified_inlier_matrix(edges, len(recon.names))
    np.testing.assert_array_equal(matrix, matrix.T)
    assert matrix[edges[0][0], edges[0][1]] == edges[0][2]
    assert (matrix > 0).sum() == 2 * len(edges)
    page = reconstruction_report(recon, ["the largest model"] * len(recon.names),
                                 jsonable(recon.to_dict()), [], [], {}).text()
    a, b, n = edges[0]
    assert f"{recon.names[a]} and {recon.names[b]}: {n} inliers" in page
    assert "The pairs whose matches verified" in page


def test_pycolmap_reads_the_two_camera_model_with_our_reprojection_error(two_camera_model):
    """pycolmap (bench extra) opens the saved model and its recomputed error is ours."""
    pycolmap = pytest.importorskip("pycolmap")
    folder = two_camera_model[2]
    model = read_colmap_text(folder / "colmap")
    theirs = pycolmap.Reconstruction(str(folder / "colmap"))
    theirs.update_point_3d_errors()  # recomputed with COLMAP's cameras: the mean over points
    assert theirs.compute_mean_reprojection_error() == pytest.approx(
        float(np.mean(model.point_errors_px())), rel=0.01)


def test_the_command_refuses_two_sizes_as_one_camera(two_camera_orbit, tmp_path):
    """--camera-mode single refuses photos of two sizes in one line (exit code 2), before
    any work."""
    photos = two_camera_orbit[0]
    for v, img in enumerate(photos[:2]):
        cv2.imwrite(str(tmp_path / f"{v:02d}.png"), img)
    proc = subprocess.run([sys.executable, "-m", "scene3D", "reconstruct-views", tmp_path,
                           "--out", tmp_path / "out", "--camera-mode", "single"],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert "photos of one camera at one size are needed" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and not (tmp_path / "out").exists()


def test_fountain_photos_of_four_cameras(fountain, tmp_path):
    """Fountain-P11's photos made into four cameras (resized by 1, 0.75, 0.6 and 0.5 and
    cropped about the centre to 100, 90, 80 and 95 %, view v by camera v mod 4; no EXIF):
    11 of 11 registered, each camera's focal length within 2 % of the truth scaled."""
    scene = read_strecha_scene(fountain)
    factors = write_camera_variants(scene.paths, tmp_path, FOUR_CAMERAS)
    truth = [cam.K[0, 0] * s for cam, s in zip(scene.cameras, factors)]
    recon = reconstruct_views(tmp_path, None, progress=lambda _: None)
    assert len(recon.cameras) == 4 and recon.main.registered.all()
    for c, camera in enumerate(recon.cameras):
        focal = camera.K[0, 0] * camera.photo_size[0] / camera.image_size[0]
        assert focal == pytest.approx(truth[c], rel=0.02)
