"""Misuse of the library gives one clear error naming the argument and what was expected."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from scene3D import SceneReconstruction3D
from scene3D.calibration import BoardSpec, detect_board
from scene3D.dense import dense_point_cloud
from scene3D.evaluation import relative_pose_error
from scene3D.features import Matches, find_matches, image_features
from scene3D.geometry.epipolar import epipolar_lines
from scene3D.io.calibration import CameraCalibration, load_calibration, save_calibration
from scene3D.selfcalibration import self_calibrate_pair
from scene3D.twoview import TwoViewSettings, reconstruct_from_matches, reconstruct_two_view
from scene3D.viz.drawing import draw_epipolar_lines
from scene3D.viz.plotting import plot_cameras_and_points, plot_point_cloud

from .helpers import correspondences


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    rng = np.random.default_rng(0)
    return cv2.GaussianBlur(rng.integers(0, 256, (120, 160, 3), dtype=np.uint8), (5, 5), 1.5)


# -- images ----------------------------------------------------------------------------

def test_find_matches_refuses_paths_with_a_hint_to_read_them():
    with pytest.raises(TypeError, match=r"`img1` must be a uint8 image.*read_image"):
        find_matches("a.jpg", "b.jpg")


def test_find_matches_refuses_none_saying_what_imread_did(image):
    with pytest.raises(TypeError, match=r"`img1` .*got None.*cv2.imread"):
        find_matches(None, image)
    with pytest.raises(TypeError, match=r"`img2` .*got None"):
        find_matches(image, None)


@pytest.mark.parametrize("bad, expected", [
    (lambda img: img.astype(float), r"`img1` must be a uint8 image .*got dtype float64"),
    (lambda img: img.astype(np.uint16), r"`img1` .*got dtype uint16.*to_bgr8"),
    (lambda img: np.dstack([img, img[..., :1]]),
     r"`img1` .*\(H, W, 3\), got shape \(120, 160, 4\)"),
    (lambda img: img[:0], r"`img1` .*got shape \(0, 160, 3\)"),
])
def test_find_matches_refuses_arrays_that_are_not_uint8_images(image, bad, expected):
    with pytest.raises(ValueError, match=expected) as info:
        find_matches(bad(image), image)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("kwargs, expected", [
    ({"ratio": -1}, r"`ratio` must be a number above 0 and at most 1, got -1"),
    ({"ratio": 2.0}, r"`ratio` .*got 2.0"),
    ({"max_features": 0}, r"`max_features` must be a whole number of at least 1, got 0"),
    ({"max_features": 100.0}, r"`max_features` .*got 100.0"),
])
def test_find_matches_refuses_nonsense_settings(image, kwargs, expected):
    with pytest.raises(ValueError, match=expected):
        find_matches(image, image, **kwargs)


def test_the_book_class_refuses_none_for_an_image_as_the_wrong_kind(camera, image):
    scene = SceneReconstruction3D(camera)
    with pytest.raises(TypeError, match=r"`img1` must be a path or a numpy array, got NoneType"):
        scene.load_image_pair(None, image)


def test_the_book_class_refuses_one_photo_as_a_pair(image):
    """The same pixels twice (a copy under another name) cannot give depth: an input
    error before any matching, not a 'pure rotation' after it."""
    scene = SceneReconstruction3D(np.array([[150.0, 0, 80], [0, 150.0, 60], [0, 0, 1]]))
    with pytest.raises(ValueError, match=r"'img1' and 'img2' are the same photo"):
        scene.load_image_pair(image, image.copy())
    scene.load_image_pair(image, image[:, ::-1].copy())


@pytest.mark.parametrize("K, expected", [
    (None, r"`K` must be a 3x3 camera matrix, got None"),
    ("K.txt", r"got 'K.txt' \(a calibration file is read by .*load_calibration\)"),
])
def test_a_path_or_none_for_K_is_the_wrong_kind(K, expected):
    with pytest.raises(TypeError, match=expected):
        SceneReconstruction3D(K)


def test_reconstruct_from_matches_refuses_settings_as_a_dict(camera, synthetic_matches):
    with pytest.raises(TypeError, match=r"`settings` must be a scene3D.TwoViewSettings "
                                        r"\(TwoViewSettings\(\*\*values\).*got dict"):
        reconstruct_from_matches(synthetic_matches.pts1, synthetic_matches.pts2, camera,
                                 {"min_matches": 10})


def test_self_calibration_refuses_a_prior_sigma_that_is_no_positive_number(
        camera, synthetic_matches):
    for bad in (-1.0, 0.0, float("nan")):
        with pytest.raises(ValueError, match=r"`prior_sigma_log` must be a number above 0"):
            self_calibrate_pair(synthetic_matches.pts1, synthetic_matches.pts2, camera, bad)


def test_drawing_and_dense_refuse_nonsense_counts_and_sizes(image):
    with pytest.raises(ValueError, match=r"`num_lines` must be a whole number of at least 1"):
        draw_epipolar_lines(image, image, np.eye(3), np.zeros((5, 2)), np.zeros((5, 2)), -3)
    K = np.array([[100.0, 0, 80], [0, 100.0, 60], [0, 0, 1]])
    for bad, expected in ((4, r"`block_size` must be odd"), (-1, r"at least 1, got -1")):
        with pytest.raises(ValueError, match=expected):
            dense_point_cloud(image, image, K, np.eye(3), np.array([1.0, 0, 0]),
                              np.zeros((5, 2)), np.zeros((5, 2)), block_size=bad)


def test_epipolar_lines_and_K_refuse_what_is_no_real_matrix(camera):
    points = np.zeros((4, 2))
    for F, expected in ((np.eye(2), r"`F` must have shape \(3, 3\), got \(2, 2\)"),
                        (np.zeros((3, 3)), r"`F` is zero"),
                        (np.eye(3) * 1j, r"`F` must be real")):
        with pytest.raises(ValueError, match=expected):
            epipolar_lines(F, points, 1)
    with pytest.raises(ValueError, match=r"`K` must be real, got complex values"):
        SceneReconstruction3D(camera + 0j)


def test_image_features_checks_its_image_too():
    with pytest.raises(TypeError, match=r"`img` .*read_image"):
        image_features("a.jpg")


def test_detect_board_refuses_none_and_float_images(image):
    board = BoardSpec()
    with pytest.raises(TypeError, match=r"`gray` must be a uint8 image.*got None.*cv2.imread"):
        detect_board(None, board)
    with pytest.raises(ValueError, match=r"`gray` must be a uint8 image.*got dtype float32"):
        detect_board(image[..., 0].astype(np.float32), board)
    with pytest.raises(TypeError, match=r"`board` must be a BoardSpec"):
        detect_board(image, (9, 6))


# -- two views -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def synthetic_matches(camera, true_pose) -> Matches:
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=120)
    return Matches(pts1, pts2, "SIFT", (120, 120))


def test_reconstruct_two_view_refuses_a_path(camera, synthetic_matches):
    with pytest.raises(TypeError, match=r"`img1` must be a uint8 image.*read_image"):
        reconstruct_two_view("a.jpg", synthetic_matches, camera)


def test_reconstruct_two_view_refuses_what_is_not_matches(camera, synthetic_matches):
    img = np.zeros((480, 640, 3), np.uint8)
    pair = (synthetic_matches.pts1, synthetic_matches.pts2)
    with pytest.raises(TypeError, match=r"`matches` must be a scene3D.features.Matches.*tuple"):
        reconstruct_two_view(img, pair, camera)


def test_reconstruct_two_view_gives_grey_points_for_a_grey_image(camera, synthetic_matches):
    grey = np.tile((np.arange(640) // 3).astype(np.uint8), (480, 1))  # value = x // 3
    result = reconstruct_two_view(grey, synthetic_matches, camera)
    assert result.colors.shape == (result.num_points, 3) and result.colors.dtype == np.uint8
    x = np.clip(np.rint(result.pts1[:, 0]).astype(int), 0, 639)
    np.testing.assert_array_equal(result.colors, np.repeat((x // 3)[:, None], 3, axis=1))


def test_a_K_for_larger_photos_is_caught_with_or_without_the_image_size(camera, true_pose):
    """Matches of 640x480 images with the K of 2560x1920 photos of the same camera: given
    the image size, refused with the factor; without it, the principal point far beyond
    the matches flags the pose (a K 4 times too large gave a pose 40 deg off, trusted,
    on fountain-P11)."""
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=200, noise_px=0.3)
    large = np.diag([4.0, 4.0, 1.0]) @ camera
    with pytest.raises(ValueError, match=r"does not fit images of 640x480.*about 4 times"):
        reconstruct_from_matches(pts1, pts2, large, image_size=(640, 480))
    result = reconstruct_from_matches(pts1, pts2, large)
    assert not result.trusted
    assert any(w.startswith("the principal point (1331, 902) of K lies far outside the "
                            "matches") and "another size" in w for w in result.warnings)
    right = reconstruct_from_matches(pts1, pts2, camera)
    assert right.trusted and right.warnings == ()
    assert reconstruct_from_matches(pts1, pts2, camera, image_size=(640, 480)).trusted
    # A K for photos twice the size passes the size check (its principal point lies at
    # the image's corner, within it); the corner is what flags it.
    double = reconstruct_from_matches(pts1, pts2, np.diag([2.0, 2.0, 1.0]) @ camera,
                                      image_size=(640, 480))
    assert not double.trusted
    assert any(w.startswith("K's principal point (666, 451) lies far from the centre of the "
                            "640x480 images: a K for photos about 2 times larger")
               for w in double.warnings)
    corner = camera.copy()
    corner[:2, 2] = 0.0  # a principal point at the image's corner: 13 deg off on Herz-Jesus
    at_corner = reconstruct_from_matches(pts1, pts2, corner, image_size=(640, 480))
    assert not at_corner.trusted
    assert any("is K for these photos?" in w for w in at_corner.warnings)


# -- TwoViewSettings -------------------------------------------------------------------

def test_two_view_settings_defaults_are_valid():
    assert TwoViewSettings() == TwoViewSettings(**dataclasses.asdict(TwoViewSettings()))


@pytest.mark.parametrize("name", [f.name for f in dataclasses.fields(TwoViewSettings)])
def test_every_two_view_setting_refuses_nan(name):
    with pytest.raises(ValueError, match=rf"TwoViewSettings\.{name} must be"):
        TwoViewSettings(**{name: float("nan")})


@pytest.mark.parametrize("kwargs, expected", [
    ({"threshold_px": -1.0}, r"threshold_px must be a finite number > 0, got -1.0"),
    ({"threshold_px": float("inf")}, r"threshold_px must be a finite number > 0"),
    ({"min_inliers": -3}, r"min_inliers must be an integer >= 5, got -3"),
    ({"max_starts": 0}, r"max_starts must be an integer >= 1, got 0"),
    ({"min_matches": 20.0}, r"min_matches must be an integer >= 5, got 20.0"),
    ({"planar_ratio": 1.5}, r"planar_ratio must be a number from 0 to 1, got 1.5"),
    ({"max_noise_cut_share": -0.1}, r"max_noise_cut_share must be a number from 0 to 1"),
    ({"uncertainty_sigmas": 0.0}, r"uncertainty_sigmas must be a finite number > 0"),
    ({"min_point_parallax_deg": 200.0}, r"min_point_parallax_deg must be a number from 0 "
                                        r"to 180"),
    ({"bundle_adjust": "yes"}, r"bundle_adjust must be True or False"),
])
def test_two_view_settings_name_the_field_and_its_range(kwargs, expected):
    with pytest.raises(ValueError, match=expected):
        TwoViewSettings(**kwargs)


def test_two_view_settings_take_inf_where_it_means_no_limit():
    s = TwoViewSettings(max_reprojection_px=np.inf, uncertainty_limit_deg=np.inf,
                        max_focal_mismatch=np.inf, max_starts=np.int64(2), threshold_px=2)
    assert s.max_reprojection_px == np.inf and s.max_starts == 2


# -- plotting --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def cloud():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(50, 3)) + [0.0, 0.0, 5.0]
    colors = rng.integers(0, 256, (50, 3), dtype=np.uint8)
    return points, colors


def test_plot_point_cloud_refuses_colours_of_another_length(cloud):
    points, colors = cloud
    with pytest.raises(ValueError, match=r"`colors` must have one row per point: 10 colours "
                                         r"for 50 points"):
        plot_point_cloud(points, colors[:10])


def test_plot_point_cloud_refuses_a_transposed_cloud(cloud):
    points, _ = cloud
    with pytest.raises(ValueError, match=r"`points3d` must have shape \(N, 3\), got \(3, 50\)"
                                         r".*transpose"):
        plot_point_cloud(points.T)
    with pytest.raises(ValueError, match=r"`colors` must have shape \(N, 3\)"):
        plot_point_cloud(points, cloud[1].T)


def test_plot_point_cloud_draws_every_point(cloud):
    points, colors = cloud
    fig = plot_point_cloud(points.tolist(), colors)
    assert fig.axes[0].collections[0].get_offsets().shape == (50, 2)


def test_plot_cameras_and_points_checks_the_poses(cloud, camera):
    points, colors = cloud
    R = np.stack([np.eye(3), np.eye(3)])
    with pytest.raises(ValueError, match=r"`t` must have shape \(V, 3\) with V = 2"):
        plot_cameras_and_points(points, colors, R, np.zeros((3, 3)), camera, (640, 480))
    with pytest.raises(ValueError, match=r"`R` must have shape \(V, 3, 3\), got \(3, 3\)"):
        plot_cameras_and_points(points, colors, np.eye(3), np.zeros(3), camera, (640, 480))
    fig = plot_cameras_and_points(points, colors, R, [[0, 0, 0], [-1, 0, 0]], camera, (640, 480))
    assert fig.axes[0].get_title() == "50 points, 2 cameras"


# -- evaluation ------------------------------------------------------------------------

def test_relative_pose_error_names_a_misshapen_argument():
    t = np.array([1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"`R_est` must have shape \(3, 3\), got \(3, 4\)"):
        relative_pose_error(np.eye(3, 4), t, np.eye(3), t)
    with pytest.raises(ValueError, match=r"`t_true` must have shape \(3,\), got \(4,\)"):
        relative_pose_error(np.eye(3), t, np.eye(3), np.ones(4))
    with pytest.raises(ValueError, match=r"`t_est` must be non-zero"):
        relative_pose_error(np.eye(3), np.zeros(3), np.eye(3), t)
    err = relative_pose_error(np.eye(3), t.reshape(3, 1), np.eye(3), -t)
    assert err.rotation_deg == 0.0 and err.translation_deg == pytest.approx(180.0)


# -- calibration -----------------------------------------------------------------------

@pytest.mark.parametrize("size", [9, (9,), (9, 6, 1), (9.0, 6.0), "96", (True, 6), (1, 6)])
def test_board_spec_refuses_a_size_that_is_not_two_integers(size):
    with pytest.raises(ValueError, match=r"`size` must be two integers >= 2 \(columns, rows\)"):
        BoardSpec(size=size)


def test_board_spec_keeps_a_list_size_as_a_tuple():
    assert BoardSpec(size=[np.int64(7), 5]).size == (7, 5)


def test_save_calibration_names_the_python_parameter(tmp_path):
    camera = CameraCalibration(np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]),
                               np.zeros(5), (640, 480))
    path = save_calibration(tmp_path / "camera.yaml", camera)
    with pytest.raises(FileExistsError, match=r"camera.yaml' exists; pass overwrite=True") as info:
        save_calibration(path, camera)
    assert "--force" not in str(info.value)
    save_calibration(path, camera, overwrite=True)
    assert load_calibration(path).image_size == (640, 480)
