"""scene3D.io.undistorted: a model's images undistorted beside transforms.json, which then
says no distortion: a point the distorted camera projects lands, in the copy, on the
pinhole projection that transforms.json gives."""

import dataclasses
import json

import cv2
import numpy as np
import pytest

from scene3D.io.colmap import colmap_model_from_views, model_for_photos
from scene3D.io.colmap_model import project_points
from scene3D.io.nerfstudio import write_nerfstudio
from scene3D.io.undistorted import (
    pinhole_model,
    undistorted_image_name,
    write_undistorted_images,
)

from .test_colmap_io import orbit_views
from .test_nerfstudio import project_nerfstudio, read_transforms

DIST = np.array([-0.3, 0.08, 1.5e-3, -1e-3])  # barrel, with a tangential part
SIGMA_PX = 1.6


def blob_image(centres: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A black BGR image with a Gaussian dot at each centre (OpenCV pixels), blue 250,
    green 120, red 40 at the peak."""
    w, h = size
    y, x = np.mgrid[0:h, 0:w]
    grey = np.zeros((h, w))
    for cx, cy in centres:
        grey += np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * SIGMA_PX**2))
    return np.round(np.clip(grey, 0, 1)[..., None] * [250, 120, 40]).astype(np.uint8)


def centroid(image: np.ndarray, near: np.ndarray, radius: int = 6) -> np.ndarray:
    """The intensity-weighted centre of the blue channel around ``near``."""
    x0, y0 = np.round(near).astype(int)
    patch = image[y0 - radius:y0 + radius + 1, x0 - radius:x0 + radius + 1, 0].astype(float)
    y, x = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    return np.array([x0 + (patch * x).sum() / patch.sum(), y0 + (patch * y).sum() / patch.sum()])


def points_at_pinhole(image: np.ndarray, model, v: int, frame: dict
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Check that view ``v``'s blobs in its undistorted 1280x960 copy ``image`` lie where
    transforms.json's pinhole ``frame`` projects its points (0.05 px; at least 8 of them
    10 px or more inside); the blobs found and the pinhole pixels of all its points."""
    mine = model.obs_view == v
    pinhole = project_nerfstudio(model.points3d[model.obs_point[mine]], frame) - 0.5
    inside = np.all((pinhole > 10) & (pinhole < [1270, 950]), axis=1)
    assert inside.sum() >= 8
    found = np.array([centroid(image, p) for p in pinhole[inside]])
    np.testing.assert_allclose(found, pinhole[inside], atol=0.05)
    return found, pinhole


def distorted_model(dist=DIST):
    """Three orbit views with a few points each, their camera at 1280x960 with ``dist``."""
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views(n_views=3,
                                                                         n_points=12)
    working = colmap_model_from_views([f"v{i}.png" for i in range(3)], K, size,
                                      np.ones(3, bool), R, t, X, colors, obs_view,
                                      obs_point, obs_xy)
    return model_for_photos(working, (1280, 960), dist)


def test_a_point_of_the_distorted_camera_lands_on_the_pinhole_projection(tmp_path):
    model = distorted_model()
    camera = model.camera(0)
    photos = {}
    for v, name in enumerate(model.names):
        mine = model.obs_view == v
        # Every point in the photo where the distorted camera puts it.
        pixels = project_points(model.points3d[model.obs_point[mine]], camera.K, camera.dist,
                                model.R[v], model.t[v])
        np.testing.assert_allclose(pixels, model.obs_xy[mine], atol=1e-6)
        photos[name] = blob_image(pixels, camera.image_size)
        cv2.imwrite(str(tmp_path / name), photos[name])
    # The photos as files in their folder, and as arrays: the same copies.
    undistorted, paths = write_undistorted_images(tmp_path / "undistorted", model, tmp_path)
    _, from_arrays = write_undistorted_images(tmp_path / "arrays", model, photos)
    for name in paths:
        assert paths[name].read_bytes() == from_arrays[name].read_bytes()
    assert list(paths) == ["v0.png", "v1.png", "v2.png"]
    write_nerfstudio(tmp_path / "transforms.json", undistorted, paths)

    data = json.loads((tmp_path / "transforms.json").read_text())
    assert (data["w"], data["h"]) == (1280, 960)
    assert all(data[k] == 0 for k in ("k1", "k2", "p1", "p2")) and "k3" not in data
    moved = []
    for v, frame in enumerate(read_transforms(tmp_path / "transforms.json")):
        image = cv2.imread(str(frame["image"]))
        assert image.shape == (960, 1280, 3)
        mine = model.obs_view == v
        found, pinhole = points_at_pinhole(image, model, v, frame)
        # The colours are the photo's, and the pinhole model has the copies' pixels.
        x, y = np.round(found[0]).astype(int)
        assert image[y, x, 0] > image[y, x, 1] > image[y, x, 2] > 0
        np.testing.assert_allclose(undistorted.obs_xy[mine], pinhole, atol=1e-6)
        moved.append(np.abs(pinhole - model.obs_xy[mine]).max())
    # Without the undistortion they would be far off: the test can fail.
    assert min(moved) > 2
    np.testing.assert_allclose(undistorted.reprojection_errors_px(), 0, atol=1e-6)


def test_an_image_of_another_size_and_names_that_collide_are_refused(tmp_path):
    model = distorted_model()
    small = {name: np.zeros((480, 640, 3), np.uint8) for name in model.names}
    with pytest.raises(ValueError, match="image 'v0.png' is 640x480, its camera is for "
                                         "1280x960 images"):
        write_undistorted_images(tmp_path, model, small)
    twins = dataclasses.replace(model, names=("a.jpg", "a.tif", "c.jpg"))
    with pytest.raises(ValueError, match="'a.jpg' and 'a.tif' would both be undistorted"):
        write_undistorted_images(tmp_path, twins, tmp_path)
    assert not list(tmp_path.iterdir())


def test_copies_are_named_png():
    assert undistorted_image_name("a/0004.JPG") == "a/0004.png"
    assert undistorted_image_name("t001.20s") == "t001.20s.png"


def test_a_pinhole_camera_keeps_its_observations():
    model = distorted_model(None)
    np.testing.assert_array_equal(pinhole_model(model).obs_xy, model.obs_xy)
