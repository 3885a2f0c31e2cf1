"""Results that save themselves: the pair's result, the book's class and the many-view
result write the commands' files (PLY, cameras.json, a COLMAP model at the photos' size,
transforms.json), and reconstruct_views takes a folder or a glob as the command does."""

import json

import cv2
import numpy as np
import pytest

from scene3D import SceneReconstruction3D
from scene3D.cli import multiview
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io.calibration import CameraCalibration, save_calibration
from scene3D.io.colmap import read_colmap_text
from scene3D.io.datasets import read_strecha_camera
from scene3D.io.export import read_ply
from scene3D.multiview import image_sources, reconstruct_views

VIEWS = ("0004.jpg", "0005.jpg", "0006.jpg")


def test_the_book_class_saves_the_pair_at_the_photos_size(rendered_pair, tmp_path):
    """The rendered pair (640x480, known pose) halved to 320x240: the COLMAP model is of
    the 640x480 images, camera 2 at the true pose (unit baseline), the points on their
    observations."""
    img1, img2, K, R, t = rendered_pair
    scene = SceneReconstruction3D(K)
    scene.load_image_pair(img1, img2, max_width=400)
    assert scene.img1.shape[:2] == (240, 320)
    written = scene.save(tmp_path / "pair")
    assert {p.name for p in written} == {"point_cloud.ply", "cameras.json", "cameras.txt",
                                         "images.txt", "points3D.txt"}
    model = read_colmap_text(tmp_path / "pair" / "colmap")
    assert model.names == ("img1", "img2")
    camera = model.camera(0)
    assert camera.image_size == (640, 480) and camera.model == "PINHOLE"
    np.testing.assert_allclose(camera.K, K, atol=1e-9)  # halved and scaled back
    np.testing.assert_allclose(model.R[0], np.eye(3), atol=1e-12)
    angle = np.degrees(np.arccos(np.clip((np.trace(model.R[1] @ R.T) - 1) / 2, -1, 1)))
    assert angle < 0.2
    assert np.degrees(np.arccos(model.t[1] @ t / np.linalg.norm(t))) < 1.0
    result = scene.reconstruct()
    assert len(model.points3d) == result.num_points
    # In the 640x480 images the errors are twice the working ones (the pair's RMSE is
    # that of the residuals' lengths).
    rmse = np.sqrt(np.mean(model.reprojection_errors_px() ** 2))
    assert rmse == pytest.approx(2 * result.reprojection_rmse_px, rel=1e-6)
    points, colors = read_ply(tmp_path / "pair" / "point_cloud.ply")
    np.testing.assert_allclose(points, result.points3d, rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(colors, result.colors)
    cameras = json.loads((tmp_path / "pair" / "cameras.json").read_text())
    assert cameras["img2"]["image_size"] == [640, 480]
    np.testing.assert_allclose(cameras["img2"]["R"], result.R)


def test_image_sources_reads_folders_globs_and_lists(tmp_path):
    folder = tmp_path / "photos"
    folder.mkdir()
    for name in ("b.jpg", "a.png", ".hidden.jpg", "notes.txt"):
        (folder / name).write_bytes(b"x")
    assert image_sources(folder) == [folder / "a.png", folder / "b.jpg"]
    assert image_sources(str(folder / "*.jpg")) == [folder / "b.jpg"]
    array = np.zeros((4, 4, 3), np.uint8)
    mixed = image_sources([folder / "b.jpg", array, str(folder)])
    assert mixed[0] == folder / "b.jpg" and mixed[1] is array and len(mixed) == 4
    with pytest.raises(FileNotFoundError, match="no image matches"):
        image_sources(str(tmp_path / "nothing" / "*.jpg"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="no image in folder"):
        image_sources(tmp_path / "empty")


@pytest.fixture(scope="module")
def small_folder(fountain, tmp_path_factory):
    """Three fountain-P11 photos stored at 768x512, and a calibration for them."""
    folder = tmp_path_factory.mktemp("small") / "photos"
    folder.mkdir()
    for name in VIEWS:
        img = cv2.imread(str(fountain / "images" / name))
        cv2.imwrite(str(folder / name), cv2.resize(img, (768, 512),
                                                   interpolation=cv2.INTER_AREA))
    K = scale_intrinsics_halved(
        read_strecha_camera(fountain / "gt_dense_cameras" / "0000.jpg.camera").K, 2)
    calib = folder.parent / "calib.yaml"
    save_calibration(calib, CameraCalibration(K, np.zeros(5), (768, 512)))
    return folder, K, calib


def test_the_many_view_result_saves_what_the_command_writes(small_folder, tmp_path):
    """reconstruct_views on a folder at 384 px: save() writes the command's model files,
    the same bytes, with the COLMAP model at the photos' 768x512."""
    folder, K, calib = small_folder
    views = reconstruct_views(folder, K, np.zeros(5), max_width=400)
    assert views.names == VIEWS and views.image_size == (384, 256)
    assert views.photo_size == (768, 512)
    written = views.save(tmp_path / "lib", images=folder)
    assert (tmp_path / "lib" / "transforms.json") in written
    out = tmp_path / "cli"
    assert multiview.main([str(folder), "--calib", str(calib), "--max-width", "400",
                           "--no-plots", "--no-report", "--out", str(out), "-q",
                           "--export", "nerfstudio"]) == 0
    for name in ("points.ply", "cameras.json", "colmap/cameras.txt", "colmap/images.txt",
                 "colmap/points3D.txt", "transforms.json"):
        assert (tmp_path / "lib" / name).read_bytes() == (out / name).read_bytes(), name
    model = read_colmap_text(tmp_path / "lib" / "colmap")
    assert model.camera(0).image_size == (768, 512)
    assert np.sqrt(np.mean(model.reprojection_errors_px() ** 2) / 2) == pytest.approx(
        2 * views.reprojection_rmse_px, rel=1e-6)


def test_the_pair_saves_its_images_undistorted_beside_transforms_json(rendered_pair, tmp_path):
    """save(images=..., undistort=True): each photo undistorted with its camera's K kept
    (as reconstruct-views --export nerfstudio --undistort writes them), transforms.json
    naming the copies with that K and no distortion; the COLMAP model keeps the lens."""
    img1, img2, K, R, t = rendered_pair
    dist = np.array([-0.2, 0.05, 1e-3, -5e-4])
    scene = SceneReconstruction3D(K)
    scene.load_image_pair(img1, img2, max_width=400)
    result = scene.reconstruct()
    photos = tmp_path / "photos"
    photos.mkdir()
    for name, image in (("a.jpg", img1), ("b.jpg", img2)):
        cv2.imwrite(str(photos / name), image)
    written = result.save(tmp_path / "pair", (320, 240), ("a.jpg", "b.jpg"), (640, 480),
                          dist, images=photos, undistort=True)
    folder = tmp_path / "pair"
    assert [p.relative_to(folder).as_posix() for p in written] == [
        "point_cloud.ply", "cameras.json", "colmap/cameras.txt", "colmap/images.txt",
        "colmap/points3D.txt", "transforms.json", "undistorted/a.png", "undistorted/b.png"]
    assert read_colmap_text(folder / "colmap").camera(0).model == "OPENCV"
    data = json.loads((folder / "transforms.json").read_text())
    assert [f["file_path"] for f in data["frames"]] == ["undistorted/a.png",
                                                        "undistorted/b.png"]
    assert data["ply_file_path"] == "point_cloud.ply"
    assert all(data[k] == 0 for k in ("k1", "k2", "p1", "p2"))
    np.testing.assert_allclose([data["fl_x"], data["fl_y"], data["cx"] - 0.5, data["cy"] - 0.5],
                               [K[0, 0], K[1, 1], K[0, 2], K[1, 2]], atol=1e-9)
    for name in ("a", "b"):
        photo = cv2.imread(str(photos / f"{name}.jpg"))
        copy = cv2.imread(str(folder / "undistorted" / f"{name}.png"))
        np.testing.assert_array_equal(copy, cv2.undistort(photo, K, dist, None, K))
        assert np.abs(copy.astype(int) - photo).max() > 50  # the lens moved the edges
    with pytest.raises(ValueError, match="`undistort` needs `images`"):
        result.save(tmp_path / "none", (320, 240), undistort=True)
    assert not (tmp_path / "none").exists()


def test_the_many_view_result_saves_undistorted_images_as_the_command_does(small_folder,
                                                                           tmp_path):
    """save(images, undistort=True) writes the bytes reconstruct-views --export nerfstudio
    --undistort writes: transforms.json and every undistorted copy."""
    folder, K, calib = small_folder
    dist = np.array([-0.05, 0.01, 0.0, 0.0, 0.0])
    lens = folder.parent / "lens.yaml"
    save_calibration(lens, CameraCalibration(K, dist, (768, 512)))
    views = reconstruct_views(folder, K, dist, max_width=400)
    written = views.save(tmp_path / "lib", images=folder, undistort=True)
    copies = sorted(p.name for p in (tmp_path / "lib" / "undistorted").iterdir())
    assert copies == [n.replace(".jpg", ".png") for n in VIEWS]
    assert {tmp_path / "lib" / "undistorted" / n for n in copies} <= set(written)
    out = tmp_path / "cli"
    assert multiview.main([str(folder), "--calib", str(lens), "--max-width", "400",
                           "--no-plots", "--no-report", "--out", str(out), "-q",
                           "--export", "nerfstudio", "--undistort"]) == 0
    for name in ("transforms.json", "colmap/cameras.txt",
                 *(f"undistorted/{n}" for n in copies)):
        assert (tmp_path / "lib" / name).read_bytes() == (out / name).read_bytes(), name
    assert json.loads((out / "transforms.json").read_text())["k1"] == 0
    assert read_colmap_text(out / "colmap").camera(0).model in ("SIMPLE_RADIAL", "OPENCV")
