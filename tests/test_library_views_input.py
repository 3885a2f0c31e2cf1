"""What the library says about the inputs of its many-view and photo functions: a K for
another image size, one path where a list of paths is expected, how to give a calibration."""

from pathlib import Path
from unittest.mock import patch

import cv2
import numpy as np
import pytest

from scene3D.cli.common import UsageError
from scene3D.cli.common import read_camera_prior as cli_read_camera_prior
from scene3D.errors import DatasetError
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.geometry.intrinsics_prior import (
    CameraMismatchError,
    ExifCamera,
    camera_prior,
    check_one_camera,
    focal_prior,
)
from scene3D.io.datasets import fetch_fountain_p11, read_strecha_camera
from scene3D.io.exif import read_camera_prior
from scene3D.io.images import load_working_images
from scene3D.multiview import image_sources, reconstruct_views

VIEWS = ("0004.jpg", "0005.jpg", "0006.jpg")


@pytest.fixture(scope="module")
def small_views(fountain: Path) -> list[np.ndarray]:
    """Three fountain-P11 photos stored at 768x512 (a quarter of the native 3072x2048)."""
    return [cv2.resize(cv2.imread(str(fountain / "images" / name)), (768, 512),
                       interpolation=cv2.INTER_AREA) for name in VIEWS]


def test_K_for_larger_photos_is_refused(fountain, small_views):
    K_native = read_strecha_camera(fountain / "gt_dense_cameras" / "0000.jpg.camera").K
    with pytest.raises(ValueError, match=r"`K` does not fit images of 768x512 px, their "
                                         r"native size, which it must be for") as info:
        reconstruct_views(small_views, K_native, max_width=None)
    assert "principal point" in str(info.value)


def test_focal_prior_for_another_size_is_refused(small_views):
    prior = focal_prior(None, (3072, 2048))
    with pytest.raises(ValueError, match=r"`focal_prior` is for 3072x2048 images, not "
                                         r"768x512 px, the images' native size"):
        reconstruct_views(small_views, None, max_width=None, focal_prior=prior)


def test_K_of_the_stored_size_passes_the_check(fountain, small_views):
    """The same K scaled to the stored size is a camera's for it (the check is on size)."""
    K_small = scale_intrinsics_halved(
        read_strecha_camera(fountain / "gt_dense_cameras" / "0000.jpg.camera").K, 2)
    result = reconstruct_views(small_views, K_small, max_width=None)
    assert result.image_size == (768, 512)
    assert result.registered.sum() == 3 and result.ok


@pytest.mark.parametrize("as_path", [str, Path])
def test_one_folder_is_taken_as_the_command_takes_it(fountain, as_path):
    """reconstruct_views(folder) reads the folder's images, sorted (as reconstruct-views
    does), rather than refusing one path (issue #51)."""
    folder = as_path(fountain / "images")
    photos = sorted((fountain / "images").glob("*.jpg"))
    assert len(photos) == 11
    assert image_sources(folder) == photos
    assert image_sources(as_path(fountain / "images" / "000[45].jpg")) == photos[4:6]


@pytest.mark.parametrize("as_path", [str, Path])
def test_one_photo_is_not_a_list_for_the_prior(fountain, as_path):
    photo = as_path(fountain / "images" / "0004.jpg")
    with pytest.raises(TypeError, match=r"`paths` must be a list of image paths, got one "
                                        r"path") as info:
        read_camera_prior(photo)
    assert "0004.jpg" in str(info.value) and "glob" in str(info.value)
    assert read_camera_prior([photo]).image_size == (3072, 2048)  # the list works


def test_one_dataset_file_is_not_a_tuple(tmp_path):
    with pytest.raises(TypeError, match=r"`files` must be a tuple of file names, got one: "
                                        r"'images/K.txt'; write \('images/K.txt',\)"):
        fetch_fountain_p11("images/K.txt", data_root=tmp_path, download=False)


SIZE = (3072, 2048)


@pytest.mark.parametrize("second, words", [
    (("b.jpg", None, (1536, 1024)), "one was resized: use the camera's originals, or resize "
                                    "the larger to 1536x1024"),
    (("b.jpg", None, (2800, 2048)), "one was cropped, or taken with another camera: use the "
                                    "camera's originals"),
])
def test_photos_of_two_sizes_are_not_told_to_give_a_calibration(second, words):
    """A calibration holds for one size too: `K` or --calib would refuse these photos
    alike (:func:`scene3D.io.images.iter_working_images`), so the message does not offer it."""
    photos = [("a.jpg", None, SIZE), second]
    with pytest.raises(ValueError, match="photos of one camera at one size are needed") as info:
        check_one_camera(photos)
    assert str(info.value).endswith(words)
    assert "`K`" not in str(info.value) and "--calib" not in str(info.value)
    images = [np.zeros((SIZE[1], SIZE[0]), np.uint8),
              np.zeros((second[2][1], second[2][0]), np.uint8)]
    with pytest.raises(ValueError) as given_K:  # the same photos with a calibration
        load_working_images(images, np.diag([2760.0, 2760.0, 1.0]), np.zeros(5), None,
                            ["a.jpg", "b.jpg"])
    assert str(given_K.value) == str(info.value)


@pytest.mark.parametrize("photos, words", [
    ([("a.jpg", ExifCamera(make="Canon", model="EOS 5D"), SIZE),
      ("b.jpg", ExifCamera(make="Apple", model="iPhone 12"), SIZE)],
     "one camera is needed"),
    ([("a.jpg", ExifCamera(focal_length_mm=35.0), SIZE),
      ("b.jpg", ExifCamera(focal_length_mm=50.0), SIZE)],
     "one focal length is needed"),
])
def test_two_cameras_are_told_how_to_give_a_calibration_in_python_or_the_shell(photos, words):
    with pytest.raises(CameraMismatchError, match=words) as info:
        check_one_camera(photos)
    assert str(info.value) == (f"{info.value.problem}; or, if one calibration holds for them "
                               "all, use its `K` (scene3D.io.calibration.load_calibration)")
    assert "--calib" not in str(info.value)
    with pytest.raises(CameraMismatchError, match=words):
        camera_prior(photos)
    with pytest.raises(UsageError) as cli:  # what the commands print without --calib
        with patch("scene3D.io.exif.read_camera_prior", side_effect=info.value):
            cli_read_camera_prior([Path("a.jpg"), Path("b.jpg")])
    assert str(cli.value) == (f"{info.value.problem}; or, if one calibration holds for them "
                              "all, give it with --calib FILE")


def test_missing_dataset_message_offers_ones_own_photos(tmp_path):
    """Own photos need no calibration (self-calibration): the message asks for none."""
    with pytest.raises(DatasetError, match="SCENE3D_DATA") as info:
        fetch_fountain_p11(("images/K.txt",), data_root=tmp_path, cache_dir=tmp_path,
                           download=False)
    assert str(info.value).endswith("or use two photos of your own (a calibration is "
                                    "optional)")
