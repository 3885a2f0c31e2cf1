"""The focal-length prior of photos without a calibration: EXIF definitions and checks."""

import math

import numpy as np
import pytest

from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.geometry.intrinsics_prior import (
    DEFAULT_PRIOR_SIGMA_LOG,
    EXIF_SIGMA_LOG,
    ExifCamera,
    camera_prior,
    check_one_camera,
    focal_35mm_from_px,
    focal_from_exif,
    focal_prior,
    focal_px_from_35mm,
    intrinsics_from_focal,
)

STRECHA = (3072, 2048)
STRECHA_FX = 2759.48  # fountain-P11's K: 0.898 x the width


def test_principal_point_at_the_centre_in_the_pixel_convention():
    K = intrinsics_from_focal(1000.0, (641, 480))
    np.testing.assert_array_equal(K, [[1000, 0, 320], [0, 1000, 239.5], [0, 0, 1]])
    # Halving keeps it at the centre of the halved image ((w/2 - 1) / 2 for even w).
    K_half = scale_intrinsics_halved(intrinsics_from_focal(1000.0, (640, 480)), 1)
    np.testing.assert_allclose(K_half[:2, 2], [(320 - 1) / 2, (240 - 1) / 2])
    with pytest.raises(ValueError, match="focal_px"):
        intrinsics_from_focal(0.0, (640, 480))


def test_35mm_equivalent_is_cipa_diagonal():
    # 3:2: the 43.27 mm diagonal and the 36 mm long side agree (OpenSfM's rule).
    assert focal_px_from_35mm(32.0, STRECHA) == pytest.approx(32.0 / 36.0 * 3072, rel=2e-4)
    # 4:3 phone photo: the diagonal gives 26 / 43.27 * 5000; the long-side rules differ.
    f = focal_px_from_35mm(26.0, (4000, 3000))
    assert f == pytest.approx(26.0 / 43.27 * 5000.0)
    assert 26.0 / 36.0 * 4000 / f == pytest.approx(0.9615, abs=1e-4)  # OpenSfM: 4 % shorter
    assert 26.0 / 35.0 * 4000 / f == pytest.approx(0.9890, abs=1e-4)  # COLMAP <= 3.12
    assert focal_35mm_from_px(f, (4000, 3000)) == pytest.approx(26.0)
    # Strecha's camera: 32.3 mm equivalent, stored as 32 it is 1 % short.
    assert focal_35mm_from_px(STRECHA_FX, STRECHA) == pytest.approx(32.34, abs=0.01)


def test_exif_35mm_is_preferred_to_focal_plane_resolution():
    exif = ExifCamera(focal_length_mm=7.4, focal_length_35mm=32,
                      focal_plane_x_resolution=10.0, focal_plane_resolution_unit=4)
    focal = focal_from_exif(exif, STRECHA)
    assert focal.focal_px == pytest.approx(focal_px_from_35mm(32, STRECHA))
    assert "FocalLengthIn35mmFilm 32 mm" in focal.description and not focal.problem


@pytest.mark.parametrize("unit, per_unit", [(2, 25.4), (3, 10.0), (4, 1.0), (5, 0.001)])
def test_focal_plane_resolution_units(unit, per_unit):
    # A 6.4 um pixel pitch: 156.25 px/mm, in the tag's unit.
    exif = ExifCamera(focal_length_mm=17.66, focal_plane_x_resolution=156.25 * per_unit,
                      focal_plane_resolution_unit=unit)
    assert focal_from_exif(exif, STRECHA).focal_px == pytest.approx(17.66 * 156.25)


def test_focal_plane_resolution_follows_a_resized_or_rotated_copy():
    exif = ExifCamera(focal_length_mm=17.66, focal_plane_x_resolution=156.25,
                      focal_plane_resolution_unit=4, pixel_x_dimension=3072,
                      pixel_y_dimension=2048)
    full = focal_from_exif(exif, STRECHA).focal_px
    assert focal_from_exif(exif, (1536, 1024)).focal_px == pytest.approx(full / 2)
    assert focal_from_exif(exif, (1024, 1536)).focal_px == pytest.approx(full / 2)
    assert "resized by 0.5" in focal_from_exif(exif, (1536, 1024)).description


def test_a_cropped_photo_uses_the_recorded_frame_and_says_so():
    exif = ExifCamera(focal_length_35mm=26, pixel_x_dimension=4000, pixel_y_dimension=3000)
    focal = focal_from_exif(exif, (3000, 3000))
    assert focal.focal_px == pytest.approx(focal_px_from_35mm(26, (4000, 3000)))
    assert "cropped from 4000x3000" in focal.description


@pytest.mark.parametrize("exif, message, problem", [
    (ExifCamera(), "no EXIF focal length", False),
    (ExifCamera(focal_length_mm=4.2), "without the sensor size", False),
    (ExifCamera(focal_length_35mm=0), "0 (unknown)", True),
    (ExifCamera(focal_length_mm=0.0, focal_plane_x_resolution=100.0,
                focal_plane_resolution_unit=4), "0 (unknown)", True),
    (ExifCamera(focal_length_35mm=5000), "implausible (a 35 mm equivalent of 5000.0 mm", True),
    (ExifCamera(focal_length_mm=5000.0, focal_plane_x_resolution=156.25,
                focal_plane_resolution_unit=4), "implausible", True),
    (ExifCamera(focal_length_35mm=2), "implausible", True),
    (ExifCamera(focal_length_mm=7.4, focal_plane_x_resolution=100.0,
                focal_plane_resolution_unit=1), "without the sensor size", False),
    (ExifCamera(error="Corrupt EXIF data"), "corrupt", True),
])
def test_unusable_exif_gives_no_focal_length_and_says_why(exif, message, problem):
    focal = focal_from_exif(exif, STRECHA)
    assert focal.focal_px is None and message in focal.description
    assert focal.problem == problem


def test_default_prior_is_colmaps_and_loose():
    prior = focal_prior(None, STRECHA)
    assert prior.source == "prior" and prior.focal_px == pytest.approx(1.2 * 3072)
    assert prior.sigma_log == DEFAULT_PRIOR_SIGMA_LOG
    # 34 % above the Strecha camera's focal length, well within two sigmas.
    assert math.log(prior.focal_px / STRECHA_FX) == pytest.approx(0.29, abs=0.01)
    np.testing.assert_allclose(prior.K[:2, 2], [1535.5, 1023.5])


def test_exif_prior():
    prior = focal_prior(ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=32),
                        STRECHA)
    assert prior.source == "exif" and prior.sigma_log == EXIF_SIGMA_LOG
    assert prior.focal_px == pytest.approx(STRECHA_FX, rel=0.011)
    assert prior.camera_name == "Canon EOS 5D" and prior.warnings == ()


def test_unusable_exif_falls_back_to_the_prior_with_a_warning():
    for exif, words in [(ExifCamera(error="Corrupt EXIF data"), "corrupt"),
                        (ExifCamera(focal_length_35mm=5000), "implausible")]:
        prior = camera_prior([("a.jpg", exif, STRECHA), ("b.jpg", None, STRECHA)])
        assert prior.source == "prior"
        assert len(prior.warnings) == 1 and "'a.jpg'" in prior.warnings[0]
        assert words in prior.warnings[0] and "not used" in prior.warnings[0]


def test_an_implausible_focal_length_next_to_a_plausible_one_is_ignored_with_a_warning():
    """5000 mm is no camera's (docs/own-photos.md, Bad input): not 'taken at 5000 mm and at
    32 mm', but a warning naming the photo, and the plausible value is used."""
    good = ("a.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=32), STRECHA)
    absurd = ("b.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=5000), STRECHA)
    for photos in ([good, absurd], [absurd, good]):
        prior = camera_prior(photos)
        assert prior.source == "exif" and prior.description == "EXIF FocalLengthIn35mmFilm 32 mm"
        assert len(prior.warnings) == 1 and prior.warnings[0].startswith(
            "'b.jpg': EXIF FocalLengthIn35mmFilm 5000 mm is implausible")
    zoomed = ("c.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=50), STRECHA)
    with pytest.raises(ValueError, match="'c.jpg' was taken at 50 mm and 'a.jpg' at 32 mm"):
        camera_prior([absurd, good, zoomed])  # two plausible ones are still compared


def test_one_photo_without_exif_shares_the_others_focal_length_with_a_warning():
    exif = ExifCamera(make="Apple", model="iPhone 12", focal_length_35mm=26)
    prior = camera_prior([("a.jpg", exif, (4032, 3024)), ("b.jpg", None, (4032, 3024))])
    assert prior.source == "exif"
    assert prior.warnings == ("'b.jpg' has no EXIF focal length: taken to share the others'",)


def test_the_default_says_why_exif_gave_no_focal_length():
    lens_only = ExifCamera(make="Acme", model="X1", focal_length_mm=4.2)
    prior = camera_prior([("a.jpg", lens_only, STRECHA), ("b.jpg", lens_only, STRECHA)])
    assert prior.source == "prior"
    assert prior.description.startswith("EXIF FocalLength 4.2 mm comes without the sensor size")
    assert "1.2 x the longer side" in prior.description
    bare = camera_prior([("a.jpg", None, STRECHA), ("b.jpg", ExifCamera(), STRECHA)])
    assert bare.description.startswith("no EXIF focal length: 1.2 x")


@pytest.mark.parametrize("second, message", [
    (("b.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=32), (3072, 1728)),
     "'b.jpg' is 3072x1728 but 'a.jpg' is 3072x2048"),
    (("b.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=32), (2048, 3072)),
     "one was rotated"),
    (("b.jpg", ExifCamera(make="Apple", model="iPhone 12", focal_length_35mm=26), STRECHA),
     "taken with a Apple iPhone 12 and 'a.jpg' with a Canon EOS 5D"),
    (("b.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=50), STRECHA),
     "taken at 50 mm and 'a.jpg' at 32 mm"),
])
def test_two_cameras_are_refused(second, message):
    first = ("a.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=32), STRECHA)
    with pytest.raises(ValueError, match=message):
        camera_prior([first, second])


def test_focal_lengths_are_compared_like_with_like():
    """A 35 mm equivalent (32) is not a real focal length (7): a photo recording both and one
    recording FocalLength only are one camera, at one zoom setting."""
    both = ("a.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_mm=7,
                                focal_length_35mm=32), STRECHA)
    real = ("b.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_mm=7), STRECHA)
    for photos in ([both, real], [real, both]):
        prior = camera_prior(photos)
        assert prior.source == "exif" and prior.description == "EXIF FocalLengthIn35mmFilm 32 mm"
    zoomed = ("c.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_mm=12), STRECHA)
    with pytest.raises(ValueError, match=r"'c.jpg' was taken at 12 mm and 'a.jpg' at 7 mm "
                                         r"\(EXIF\): one focal length is needed"):
        camera_prior([both, real, zoomed])
    wide = ("d.jpg", ExifCamera(make="Canon", model="EOS 5D", focal_length_35mm=24), STRECHA)
    with pytest.raises(ValueError, match=r"'d.jpg' was taken at 24 mm and 'a.jpg' at 32 mm "
                                         r"\(EXIF, 35 mm equivalent\)"):
        camera_prior([both, real, wide])


def test_one_camera_passes():
    exif = ExifCamera(make="Canon", model="Canon EOS 5D", focal_length_35mm=32)
    check_one_camera([("a", exif, STRECHA), ("b", exif, STRECHA), ("c", None, STRECHA)])
    assert exif.camera_name == "Canon EOS 5D"  # the make is not repeated
