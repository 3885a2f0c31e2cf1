"""Reading EXIF with Pillow from real files (written by Pillow in a temporary folder)."""

import re
import zlib

import numpy as np
import pytest
from PIL import ExifTags, Image

from scene3D.geometry.intrinsics_prior import focal_px_from_35mm
from scene3D.io.exif import read_camera_prior, read_exif

from .exif_blocks import exif_block

SIZE = (96, 64)


def exif_bytes(make="Canon", model="Canon EOS 5D", focal_35mm=None, focal_mm=None,
               plane_res=None, plane_unit=None, pixel_dims=None, orientation=None) -> bytes:
    width, height = pixel_dims if pixel_dims is not None else (None, None)
    return exif_block({ExifTags.Base.Make: make, ExifTags.Base.Model: model,
                       ExifTags.Base.Orientation: orientation},
                      {ExifTags.Base.FocalLengthIn35mmFilm: focal_35mm,
                       ExifTags.Base.FocalLength: focal_mm,
                       ExifTags.Base.FocalPlaneXResolution: plane_res,
                       ExifTags.Base.FocalPlaneResolutionUnit: plane_unit,
                       ExifTags.Base.ExifImageWidth: width,
                       ExifTags.Base.ExifImageHeight: height}).tobytes()


def save(path, exif: bytes | None = None, size=SIZE):
    rng = np.random.default_rng(0)
    img = Image.fromarray((rng.random((size[1], size[0], 3)) * 255).astype(np.uint8))
    img.save(path, **({"exif": exif} if exif is not None else {}))
    return path


def test_reads_the_camera_tags(tmp_path):
    path = save(tmp_path / "a.jpg", exif_bytes(focal_35mm=32, focal_mm=7.4, plane_res=2000.0,
                                              plane_unit=3, pixel_dims=(3072, 2048),
                                              orientation=6))
    exif = read_exif(path)
    assert exif.error is None and exif.camera_name == "Canon EOS 5D"
    assert exif.focal_length_35mm == 32 and exif.focal_length_mm == pytest.approx(7.4)
    assert exif.focal_plane_x_resolution == pytest.approx(2000.0)
    assert exif.focal_plane_resolution_unit == 3
    assert (exif.pixel_x_dimension, exif.pixel_y_dimension) == (3072, 2048)
    assert exif.orientation == 6  # recorded, not applied


def test_no_exif_is_none(tmp_path):
    assert read_exif(save(tmp_path / "plain.jpg")) is None
    assert read_exif(save(tmp_path / "plain.png")) is None
    with pytest.raises(FileNotFoundError, match="nope.jpg"):
        read_exif(tmp_path / "nope.jpg")
    with pytest.raises(FileNotFoundError, match="a folder, not an image file"):
        read_exif(tmp_path)


@pytest.mark.parametrize("damage, message", [
    (lambda tiff: tiff[:4] + b"\x08\x00\x00\x00\xff\xff" + tiff[10:], "Corrupt EXIF data"),
    (lambda tiff: b"XXXX" + tiff[4:], "does not parse as TIFF"),
    (lambda tiff: tiff[:4] + b"\xff\xff\x00\x00" + tiff[8:], "Corrupt EXIF data"),
])
def test_a_corrupt_block_is_reported_not_ignored(tmp_path, damage, message):
    good = save(tmp_path / "good.jpg", exif_bytes(focal_35mm=32)).read_bytes()
    start = good.index(b"Exif\x00\x00") + 6
    tiff = good[start:start + 64]
    (tmp_path / "bad.jpg").write_bytes(good[:start] + damage(tiff) + good[start + 64:])
    exif = read_exif(tmp_path / "bad.jpg")
    assert exif is not None and message in exif.error
    prior = read_camera_prior([tmp_path / "bad.jpg"])
    assert prior.source == "prior" and "corrupt" in prior.warnings[0]


def test_camera_prior_of_photos(tmp_path):
    exif = exif_bytes(focal_35mm=32)
    paths = [save(tmp_path / f"{i}.jpg", exif) for i in range(3)]
    prior = read_camera_prior(paths)
    assert prior.source == "exif" and prior.image_size == SIZE
    assert prior.focal_px == pytest.approx(focal_px_from_35mm(32, SIZE))
    assert prior.camera_name == "Canon EOS 5D"


def test_camera_prior_refuses_two_cameras(tmp_path):
    a = save(tmp_path / "a.jpg", exif_bytes(focal_35mm=32))
    b = save(tmp_path / "b.jpg", exif_bytes(make="Apple", model="iPhone 12", focal_35mm=26))
    # The photos by their paths as given, as every message names an image.
    with pytest.raises(ValueError, match=re.escape(f"'{b}' was taken with a Apple iPhone 12 "
                                                   f"and '{a}' with a Canon EOS 5D")):
        read_camera_prior([a, b])
    c = save(tmp_path / "c.jpg", exif_bytes(focal_35mm=32), size=(64, 96))
    with pytest.raises(ValueError, match="one was rotated"):
        read_camera_prior([a, c])


def test_absurd_focal_length_is_not_used(tmp_path):
    path = save(tmp_path / "a.jpg", exif_bytes(focal_35mm=5000))
    prior = read_camera_prior([path])
    assert prior.source == "prior" and "implausible" in prior.warnings[0]


def test_absurd_focal_length_next_to_a_plausible_one_is_warned_about(tmp_path, caplog):
    a = save(tmp_path / "a.jpg", exif_bytes(focal_35mm=32))
    b = save(tmp_path / "b.jpg", exif_bytes(focal_35mm=5000))
    with caplog.at_level("WARNING", logger="scene3D.io.exif"):
        prior = read_camera_prior([a, b])
    assert prior.source == "exif"
    assert prior.focal_px == pytest.approx(focal_px_from_35mm(32, SIZE))
    assert f"'{b}': EXIF FocalLengthIn35mmFilm 5000 mm is implausible" in caplog.text


def test_a_35mm_equivalent_is_not_compared_with_a_real_focal_length(tmp_path):
    """One camera: 'a.jpg' records FocalLength 7 mm and its 35 mm equivalent 32 mm, 'b.jpg'
    FocalLength 7 mm only. Not 'taken at 7 mm and at 32 mm': one focal length, from 'a.jpg'."""
    a = save(tmp_path / "a.jpg", exif_bytes(focal_35mm=32, focal_mm=7.0))
    b = save(tmp_path / "b.jpg", exif_bytes(focal_mm=7.0))
    for paths in ([a, b], [b, a]):
        prior = read_camera_prior(paths)
        assert prior.source == "exif"
        assert prior.focal_px == pytest.approx(focal_px_from_35mm(32, SIZE))


def test_a_photo_pillow_will_not_open_has_no_exif_not_a_corrupt_one(tmp_path, caplog):
    """Pillow refuses more than 2 x MAX_IMAGE_PIXELS (DecompressionBombError) before reading a
    pixel: not a corrupt EXIF block; reading the image reports what is wrong with it."""
    path = save(tmp_path / "a.png")
    data = bytearray(path.read_bytes())
    data[16:24] = (100000).to_bytes(4, "big") * 2  # IHDR: 100000x100000
    data[29:33] = zlib.crc32(data[12:29]).to_bytes(4, "big")
    path.write_bytes(bytes(data))
    with caplog.at_level("WARNING", logger="scene3D.io.exif"):
        assert read_exif(path) is None
    assert "'" + str(path) + "': Pillow will not open it" in caplog.text
