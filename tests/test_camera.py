import re

import cv2
import numpy as np
import pytest

from scene3D.geometry.camera import (
    adapt_intrinsics_to_size,
    check_intrinsics_for_size,
    principal_point_hint,
    scale_intrinsics_resize,
    validate_distortion,
    validate_intrinsics,
)

K = np.array([[800.0, 0.0, 331.3], [0.0, 790.0, 247.6], [0.0, 0.0, 1.0]])


def _blob(size, center, sigma=3.0):
    w, h = size
    x, y = np.meshgrid(np.arange(w), np.arange(h))
    img = 255 * np.exp(-((x - center[0]) ** 2 + (y - center[1]) ** 2) / (2 * sigma**2))
    return img.astype(np.float32)


def _centroid(img):
    y, x = np.mgrid[: img.shape[0], : img.shape[1]]
    return np.array([(x * img).sum(), (y * img).sum()]) / img.sum()


def test_resize_scaling_keeps_pixel_centres():
    center = np.array([301.3, 211.7])
    img = _blob((640, 480), center, sigma=5.0)
    small = cv2.resize(img, (320, 240), interpolation=cv2.INTER_AREA)
    K2 = scale_intrinsics_resize(K, (640, 480), (320, 240))
    assert K2[0, 2] == pytest.approx(0.5 * (K[0, 2] + 0.5) - 0.5)
    np.testing.assert_allclose(_centroid(small), 0.5 * (center + 0.5) - 0.5, atol=0.02)


def test_adapt_intrinsics():
    np.testing.assert_allclose(adapt_intrinsics_to_size(K, (640, 480), (640, 480)), K)
    half = adapt_intrinsics_to_size(K, (640, 480), (320, 240))
    assert half[0, 0] == pytest.approx(400.0)
    with pytest.raises(ValueError, match=r"images are 640x360 but the calibration is for "
                                         r"640x480, another aspect ratio: cropped images"):
        adapt_intrinsics_to_size(K, (640, 480), (640, 360))


@pytest.mark.parametrize("image_size", [(480, 640), (240, 320)])
def test_adapt_intrinsics_says_the_images_are_turned(image_size):
    """Portrait images with a landscape calibration (the camera turned, its pixels stored
    upright): turned by 90 degrees, not cropped; also when stored smaller."""
    w, h = image_size
    with pytest.raises(ValueError) as info:
        adapt_intrinsics_to_size(K, (640, 480), image_size, what="its camera file")
    assert str(info.value) == (
        f"images are {w}x{h} but its camera file is for 640x480: the images are turned by "
        "90 degrees from it (portrait against landscape); turn them back to landscape "
        "(scene3D uses the pixels as stored, not the EXIF orientation)")


@pytest.mark.parametrize("bad, message", [
    (np.eye(2), r"`K` must have shape \(3, 3\), got \(2, 2\)"),
    (np.diag([-1.0, 1.0, 1.0]), "positive focal"),
    (np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, np.nan]]), "non-finite"),
    (np.array([[1.0, 0, 0], [0, 1, 0], [1, 0, 1]]), "last row"),
    (np.array([[500.0, 60, 320], [0, 500, 240], [0, 0, 1]]), "skew of 60 px against fx=500"),
])
def test_invalid_intrinsics(bad, message):
    with pytest.raises(ValueError, match=message):
        validate_intrinsics(bad)


def test_distortion_lengths():
    assert validate_distortion(None).size == 0
    for n in (0, 4, 5, 8, 12, 14):
        assert validate_distortion(np.zeros((1, n))).shape == (n,)
    with pytest.raises(ValueError, match="got 3"):
        validate_distortion([0.1, 0.0, 0.0])


def test_intrinsics_that_no_camera_has_for_the_image_size():
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    check_intrinsics_for_size(K, (640, 480))
    far = K.copy()
    far[0, 2] = -400  # more than half the width left of the image
    with pytest.raises(ValueError, match=r"\(-400, 240\) lies far outside the 640x480 image"):
        check_intrinsics_for_size(far, (640, 480))
    far[0, 2], far[1, 2] = 900, -200  # within half the image of its edges: a crop's
    check_intrinsics_for_size(far, (640, 480))
    for fx, fy, message in ((0.001, 0.001, "fx=0.001 px is not a camera's for a 640x480"),
                            (1e12, 1e12, "fx=1e+12 px"),
                            (500, 5, "fy=5 px is not"),
                            (500, 100, "fx=500 and fy=100 px differ")):
        odd = K.copy()
        odd[0, 0], odd[1, 1] = fx, fy
        with pytest.raises(ValueError, match=re.escape(message)):
            check_intrinsics_for_size(odd, (640, 480))
    wide, long = K.copy(), K.copy()
    wide[0, 0] = wide[1, 1] = 0.25 * 640  # a fisheye's
    long[0, 0] = long[1, 1] = 50 * 640  # a 1800 mm lens on a full-frame sensor
    check_intrinsics_for_size(wide, (640, 480))
    check_intrinsics_for_size(long, (640, 480))


def test_principal_point_hint_names_larger_turned_or_misplaced_calibrations():
    K = np.array([[800.0, 0, 319.5], [0, 800.0, 239.5], [0, 0, 1]])  # for 640x480
    assert principal_point_hint(K, (640, 480)) == ""
    off = K.copy()
    off[0, 2] += 0.15 * 640  # within the limit of 20 % of the width
    assert principal_point_hint(off, (640, 480)) == ""
    assert principal_point_hint(np.diag([2.0, 2.0, 1.0]) @ K, (640, 480)).endswith(
        "a K for photos about 2 times larger (about 1280x960)? "
        "scene3D.geometry.camera.scale_intrinsics"
        "(K, 640 / W, 480 / H), W x H the size it was calibrated at, fits it to these")
    wide = np.array([[900.0, 0, 479.5], [0, 900.0, 319.5], [0, 0, 1]])  # for 960x640
    assert "a K for the photos turned by 90 degrees?" in principal_point_hint(wide, (640, 960))
    corner = K.copy()
    corner[:2, 2] = 0.0
    assert principal_point_hint(corner, (640, 480)) == (
        "K's principal point (0, 0) lies far from the centre of the 640x480 images (a "
        "calibrated camera's lies within a few per cent of it; a crop moves it): is K for "
        "these photos?")

