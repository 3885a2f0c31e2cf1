import numpy as np
import pytest
from matplotlib.figure import Figure

from scene3D import ReconstructionError, SceneReconstruction3D
from scene3D.evaluation import relative_pose_error
from scene3D.geometry.camera import scale_intrinsics


@pytest.fixture(scope="module")
def scene(rendered_pair):
    img1, img2, K, _, _ = rendered_pair
    s = SceneReconstruction3D(K, np.zeros(5))
    s.load_image_pair(img1, img2)
    return s


def test_book_api_recovers_the_pose_and_sets_the_book_attributes(scene, rendered_pair):
    _, _, K, R, t = rendered_pair
    result = scene.reconstruct("SIFT")
    err = relative_pose_error(result.R, result.t, R, t)
    assert err.rotation_deg < 0.1 and err.translation_deg < 0.5
    assert scene.F.shape == scene.E.shape == (3, 3)
    np.testing.assert_allclose(scene.Rt1, np.hstack([np.eye(3), np.zeros((3, 1))]))
    np.testing.assert_allclose(scene.Rt2, np.hstack([result.R, result.t[:, None]]))
    assert scene.match_pts1.shape == scene.match_pts2.shape == (result.num_matches, 2)
    assert scene.match_inliers1.shape == (result.num_inliers, 2)
    np.testing.assert_allclose(scene.K, K)  # 640 px wide: not halved


def test_plots_return_figures_and_reuse_the_features(scene):
    matches = scene.matches("SIFT")
    result = scene.reconstruct("SIFT")
    for fig in (scene.plot_optic_flow(), scene.draw_epipolar_lines(),
                scene.plot_rectified_images(), scene.plot_point_cloud()):
        assert isinstance(fig, Figure) and fig.axes
    assert scene.matches("sift") is matches  # computed once, reused by every plot
    assert scene.reconstruct() is result


def test_the_pair_summary_is_a_library_call_and_json_ready(scene, rendered_pair, tmp_path):
    """What chapter4.py writes to reconstruction.json, from a notebook in one call: the
    result's pose and K, a calibration file's source, the sizes, and JSON that reads back."""
    import json
    from pathlib import Path

    from scene3D.io.export import write_json
    from scene3D.twoview.summary import pair_summary

    _, _, K, R, t = rendered_pair
    result = scene.reconstruct("SIFT")
    summary = pair_summary(result, (Path("a.png"), Path("b.png")), (640, 480),
                           scene.native_size, "sift", {"total": 1.5}, Path("cam.yaml"))
    assert summary["calibration_source"] == "file" and summary["self_calibration"] is None
    assert summary["inputs"] == {"image1": "a.png", "image2": "b.png", "calibration": "cam.yaml"}
    assert "dense" not in summary and summary["timings_s"] == {"total": 1.5}
    back = json.loads(write_json(tmp_path / "s.json", summary).read_text())
    np.testing.assert_allclose(back["R"], result.R)
    np.testing.assert_allclose(back["K"], K)
    assert relative_pose_error(np.array(back["R"]), np.array(back["t"]), R, t).rotation_deg < 0.1
    assert back["num_inliers"] == result.num_inliers and back["trusted"] == result.trusted


def test_halving_scales_K_exactly(rendered_pair):
    img1, img2, K, R, t = rendered_pair
    # Each pixel repeated as a 4x4 block: pixel x of the rendering is centred at 4x + 1.5.
    big1 = np.kron(img1, np.ones((4, 4, 1), np.uint8))[:, :, :3]  # 2560 x 1920
    big2 = np.kron(img2, np.ones((4, 4, 1), np.uint8))[:, :, :3]
    K_big = scale_intrinsics(K, 4.0, 4.0)
    s = SceneReconstruction3D(K_big)
    s.load_image_pair(big1, big2)
    assert s.native_size == (2560, 1920) and s.halvings == 2  # 2560 -> 1280 -> 640
    assert np.array_equal(s.img1, img1)  # averaging 4x4 blocks gives the rendering back
    np.testing.assert_allclose(s.K, K)
    s2 = SceneReconstruction3D(K_big)
    s2.load_image_pair(big1, big2, use_pyr_down=False)
    assert s2.img1.shape == big1.shape


def test_array_inputs_in_other_formats(rendered_pair):
    img1, img2, K, R, t = rendered_pair
    grey = img1.mean(axis=2).astype(np.uint8)
    rgba = np.dstack([img2, np.full(img2.shape[:2], 255, np.uint8)])
    s = SceneReconstruction3D(K)
    s.load_image_pair(grey, rgba.astype(np.uint16) * 257)
    assert s.img1.shape == s.img2.shape == (480, 640, 3) and s.img2.dtype == np.uint8


def test_distortion_is_removed(rendered_pair):
    import cv2

    img1, img2, K, R, t = rendered_pair
    dist = np.array([-0.05, 0.01, 0.0, 0.0, 0.0])
    # Distort the renderings with the model, then let the class undo it.
    h, w = img1.shape[:2]
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 1, 2).astype(float)
    undist = cv2.undistortPoints(grid, K, dist, P=K).reshape(h, w, 2).astype(np.float32)
    d1 = cv2.remap(img1, undist[..., 0], undist[..., 1], cv2.INTER_LINEAR)
    d2 = cv2.remap(img2, undist[..., 0], undist[..., 1], cv2.INTER_LINEAR)
    s = SceneReconstruction3D(K, dist)
    s.load_image_pair(d1, d2)
    err = relative_pose_error(*(lambda r: (r.R, r.t))(s.reconstruct()), R, t)
    assert err.rotation_deg < 0.2 and err.translation_deg < 1.0


def test_pure_rotation_raises(rotated_pair):
    img1, img2, K = rotated_pair
    s = SceneReconstruction3D(K)
    s.load_image_pair(img1, img2)
    with pytest.raises(ReconstructionError, match="pure rotation"):
        s.plot_point_cloud()


def test_bad_inputs(tmp_path, rendered_pair):
    img1, img2, K, _, _ = rendered_pair
    with pytest.raises(ValueError, match=r"`K` must have shape \(3, 3\)"):
        SceneReconstruction3D(np.eye(4))
    with pytest.raises(ValueError, match="coefficients, got 2"):
        SceneReconstruction3D(K, [0.1, 0.2])
    s = SceneReconstruction3D(K)
    with pytest.raises(FileNotFoundError, match="nope.jpg"):
        s.load_image_pair(tmp_path / "nope.jpg", img1)
    with pytest.raises(ValueError, match=r"'img2' is \d+x200 but 'img1' is \d+x\d+: photos of "
                                         "one camera at one size are needed"):
        s.load_image_pair(img1, img1[:200])
    with pytest.raises(ValueError, match="unknown feature mode 'HOG'"):
        s.load_image_pair(img1, img2)
        s.reconstruct("HOG")
    with pytest.raises(RuntimeError, match="load_image_pair"):
        SceneReconstruction3D(K).reconstruct()


def test_a_K_for_larger_photos_is_refused_not_trusted(fountain, tmp_path):
    """K of the 3072x2048 originals with photos stored at 768x512: the principal point
    (1520, 1007) lies far outside them. It gave a pose 39 deg off, marked trusted."""
    import cv2

    from scene3D.io.datasets import read_strecha_camera

    cam = read_strecha_camera(fountain / "gt_dense_cameras" / "0004.jpg.camera")
    paths = []
    for name in ("0004.jpg", "0005.jpg"):
        small = cv2.resize(cv2.imread(str(fountain / "images" / name)), (768, 512),
                           interpolation=cv2.INTER_AREA)
        paths.append(tmp_path / name)
        cv2.imwrite(str(paths[-1]), small)
    scene = SceneReconstruction3D(cam.K)
    with pytest.raises(ValueError, match=r"`K` does not fit images of 768x512 px.*principal.*"
                                         r"a K for photos about 4 times larger "
                                         r"\(about 3072x2048\)\? "
                                         r"scene3D.geometry.camera.scale_intrinsics\(K, 768 / W"):
        scene.load_image_pair(*paths)
