"""HEIC/HEIF photos (iPhones' default format) through pillow-heif: pixels and size as
stored, EXIF, a pose against the Strecha ground truth, AVIF left to OpenCV, and the
message without pillow-heif."""

import sys

import cv2
import numpy as np
import pytest

from scene3D import SceneReconstruction3D
from scene3D.evaluation import relative_pose_error
from scene3D.io.datasets import read_strecha_camera, relative_pose
from scene3D.io.exif import read_camera_prior, read_exif
from scene3D.io.images import read_image, read_image_size

from .exif_blocks import exif_block

pillow_heif = pytest.importorskip("pillow_heif")


def _save_heic(path, bgr, exif=None):
    from PIL import Image

    pillow_heif.register_heif_opener()
    kwargs = {"quality": 95}
    if exif is not None:
        kwargs["exif"] = exif.tobytes()
    Image.fromarray(bgr[:, :, ::-1]).save(path, format="HEIF", **kwargs)


def _iphone_exif(orientation=1):
    return exif_block({0x010F: "Apple", 0x0110: "iPhone 13", 0x0112: orientation},
                      {0x920A: 5.1, 0xA405: 26})  # FocalLength (mm), FocalLengthIn35mmFilm


@pytest.fixture(scope="module")
def heic_pair(fountain, tmp_path_factory):
    """The book's pair at 1536x1024 saved as HEIC, with the camera files' K scaled."""
    folder = tmp_path_factory.mktemp("heic")
    paths = []
    for name in ("0004.jpg", "0005.jpg"):
        img = cv2.resize(cv2.imread(str(fountain / "images" / name)), (1536, 1024),
                         interpolation=cv2.INTER_AREA)
        paths.append(folder / name.replace(".jpg", ".heic"))
        _save_heic(paths[-1], img, _iphone_exif())
    return paths


def test_a_heic_photo_reads_as_its_pixels(heic_pair, fountain):
    img = read_image(heic_pair[0])
    assert img.shape == (1024, 1536, 3) and img.dtype == np.uint8
    assert read_image_size(heic_pair[0]) == (1536, 1024)
    jpeg = cv2.resize(cv2.imread(str(fountain / "images" / "0004.jpg")), (1536, 1024),
                      interpolation=cv2.INTER_AREA)
    # BGR, not RGB: the HEVC round trip at quality 95 stays within a few grey levels.
    assert np.mean(np.abs(img.astype(float) - jpeg)) < 4.0


def test_a_heic_pair_gives_the_true_pose(heic_pair, fountain):
    from scene3D.geometry.camera import scale_intrinsics

    cams = [read_strecha_camera(fountain / "gt_dense_cameras" / f"000{i}.jpg.camera")
            for i in (4, 5)]
    scene = SceneReconstruction3D(scale_intrinsics(cams[0].K, 0.5, 0.5))
    scene.load_image_pair(*heic_pair)
    result = scene.reconstruct()
    error = relative_pose_error(result.R, result.t, *relative_pose(*cams))
    assert result.trusted and error.max_deg < 0.5


def test_a_heic_photos_exif_gives_the_focal_prior(heic_pair):
    exif = read_exif(heic_pair[0])
    assert exif is not None and exif.camera_name == "Apple iPhone 13"
    prior = read_camera_prior(heic_pair)
    # 26 mm equivalent on a 36 mm-wide frame: 26 / 36 of the 1536 px side, give or take
    # the aspect ratio's crop: the EXIF, not the 1.2 x default (1843 px).
    assert prior.source == "exif" and abs(prior.focal_px - 1536 * 26 / 36) < 0.25 * 1536


@pytest.mark.parametrize("orientation", [1, 2, 3, 4, 5, 6, 7, 8])
def test_a_heic_photo_keeps_its_stored_layout(tmp_path, orientation):
    """iPhones store a portrait photo's turn in the file (irot, and EXIF orientation);
    libheif applies it, and the package undoes it: the pixels as stored, as for a JPEG."""
    img = np.zeros((480, 640, 3), np.uint8)
    img[:240, :320] = 255  # the top-left quarter white, as the sensor saw it
    path = tmp_path / f"o{orientation}.heic"
    _save_heic(path, img, _iphone_exif(orientation))
    stored = read_image(path)
    assert stored.shape == (480, 640, 3) and read_image_size(path) == (640, 480)
    assert stored[5:235, 5:315].min() > 200 and stored[245:, :].max() < 50
    assert stored[:, 325:].max() < 50


def test_without_pillow_heif_the_message_says_how(heic_pair, monkeypatch):
    monkeypatch.setitem(sys.modules, "pillow_heif", None)  # import fails
    with pytest.raises(ValueError, match=r"a HEIC/HEIF photo, which needs pillow-heif "
                                         r"\(pip install 'scene3D\[heic\]'\)"):
        read_image(heic_pair[0])


def test_an_avif_naming_mif1_first_is_left_to_opencv(tmp_path):
    """AVIF files share HEIF's container; one may name mif1 as its major brand with avif
    among its compatible ones. OpenCV decodes AVIF; libheif here has no AV1 decoder."""
    from scene3D.io.images import is_heif

    ftyp = (b"\x00\x00\x00\x1cftyp" + b"mif1" + b"\x00\x00\x00\x00" + b"mif1avifmiaf")
    assert not is_heif(ftyp)
    assert is_heif(b"\x00\x00\x00\x18ftypheic\x00\x00\x00\x00mif1heic")
