"""Many views without a calibration file: one focal length found by the photos
(scene3D.multiview.focal), synthetic views first, then fountain-P11 end to end."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import ExifTags, Image

from scene3D.evaluation import camera_set_error
from scene3D.evaluation.synthetic import orbit_poses
from scene3D.geometry import project
from scene3D.io.datasets import read_strecha_camera
from scene3D.multiview import PairMatches, SfMSettings, ViewFeatures, reconstruct_models
from scene3D.multiview.focal import FocalSettings

from .exif_blocks import exif_block

#: Square pixels, the principal point off the image centre by 1.5 % and 2 % (the model
#: puts it at the centre: the focal length must still come out close).
K_TRUE = np.array([[520.0, 0, 329.0], [0, 520.0, 229.0], [0, 0, 1]])
SIZE = (640, 480)


def _orbit_views(noise_px, seed=0, views=8):
    """Points of a courtyard seen from :func:`scene3D.evaluation.synthetic.orbit_poses` cameras, as
    keypoints in an order unrelated to the points, and every pair's true matches."""
    rng = np.random.default_rng(seed)
    Rs, ts = orbit_poses(2 * views)
    Rs, ts = Rs[:views], ts[:views]  # half an orbit: neighbours overlap
    X = rng.uniform([-7, -4, -7], [7, 2, 7], (1000, 3))
    features, ids = [], []
    for R, t in zip(Rs, ts):
        pix = project(X, K_TRUE, R, t)
        depth = (X @ R.T + t)[:, 2]
        seen = np.flatnonzero((depth > 0) & np.all((pix > 0) & (pix < SIZE), axis=1))
        order = rng.permutation(seen)
        kp = pix[order] + rng.normal(0, noise_px, (len(order), 2))
        features.append(ViewFeatures(kp, np.zeros((len(order), 1), np.float32),
                                     np.zeros((len(order), 3), np.uint8)))
        ids.append(order)
    pairs = []
    for i in range(views):
        for j in range(i + 1, views):
            _, a, b = np.intersect1d(ids[i], ids[j], return_indices=True)
            if len(a) >= 30:
                pairs.append(PairMatches(i, j, a, b, len(a)))
    return features, pairs, Rs, ts


@pytest.mark.parametrize("start", [1.3, 0.7])
def test_synthetic_views_find_the_focal_length_from_30_percent_off(start):
    """The prior 30 % too long or too short (with the default prior's sigma): every view
    registered, the focal length within 0.5 % of the truth (the principal point, 1.5-2 %
    off the centre, is the model's error) and within its sigma's reach, the cameras
    close to the truth."""
    features, pairs, Rs, ts = _orbit_views(0.5)
    K0 = np.array([[520.0 * start, 0, 319.5], [0, 520.0 * start, 239.5], [0, 0, 1]])
    focal = FocalSettings(520.0 * start, 0.5, "prior")
    models, reasons, _ = reconstruct_models(features, pairs, K0, SfMSettings(), focal=focal)
    model = models[0]
    assert len(models) == 1 and model.registered.all() and reasons == {}
    assert model.focal.source == "prior+refined" and model.focal.determined
    assert model.focal.trusted and model.focal.prior_focal_px == 520.0 * start
    error = model.K[0, 0] / 520.0 - 1.0
    assert abs(error) < 5e-3
    assert abs(math.log1p(error)) < 3 * model.focal.sigma_px / model.focal.focal_px
    assert model.K[0, 0] == model.K[1, 1] == model.focal.focal_px
    np.testing.assert_allclose(model.K[:2, 2], [319.5, 239.5])  # the centre, held
    centers_true = -np.einsum("vji,vj->vi", Rs, ts)
    err = camera_set_error(model.R, model.centers, Rs, centers_true)
    assert err.rotation_errors_deg.max() < 1.5  # the principal point's 1-1.3 deg offset
    assert err.center_errors.max() < 0.02  # likewise
    assert model.reprojection_rmse_px < 0.8


def test_a_further_model_too_small_to_refine_inherits_the_focal_length():
    """Six views of one scene and two of another, unconnected: the second model, of two
    views (fewer than ``FocalSettings.min_views``), keeps the first's focal length and
    says so (source ``inherited``, no start pair), not "prior+refined" as if its own
    views had refined it."""
    features, pairs, _, _ = _orbit_views(0.5, seed=0, views=6)
    more, more_pairs, _, _ = _orbit_views(0.5, seed=1, views=2)
    features += more
    pairs += [PairMatches(p.i + 6, p.j + 6, p.idx_i, p.idx_j, p.num_inliers) for p in more_pairs]
    focal = FocalSettings(520.0 * 1.2, 0.5, "prior")
    K0 = np.array([[focal.prior_focal_px, 0, 319.5], [0, focal.prior_focal_px, 239.5],
                   [0, 0, 1]])
    models, reasons, _ = reconstruct_models(features, pairs, K0, SfMSettings(), focal=focal)
    assert [int(m.registered.sum()) for m in models] == [6, 2] and reasons == {}
    first, second = models
    assert first.focal.source == "prior+refined" and first.focal.start_pair is not None
    assert second.focal.source == "inherited" and second.focal.start_pair is None
    assert second.K[0, 0] == first.K[0, 0] == second.focal.start_focal_px
    assert second.focal.trusted and second.focal.warnings == ()


def test_views_that_cannot_tell_keep_the_prior_and_say_so():
    """Views that translate sideways without turning, looking the same way: the
    focal length and the depths trade off exactly (H&Z section 19.5), so the prior's
    value is kept, the model adjusted under it, and the estimate flagged."""
    rng = np.random.default_rng(5)
    X = rng.uniform([-3, -2, 8], [3, 2, 12], (1500, 3))
    views = 5
    features, ids = [], []
    for v in range(views):
        pix = project(X, K_TRUE, np.eye(3), np.array([-0.5 * v, 0.05 * v, 0.0]))
        seen = np.flatnonzero(np.all((pix > 0) & (pix < SIZE), axis=1))
        kp = pix[seen] + rng.normal(0, 0.3, (len(seen), 2))
        features.append(ViewFeatures(kp, np.zeros((len(seen), 1), np.float32),
                                     np.zeros((len(seen), 3), np.uint8)))
        ids.append(seen)
    pairs = [PairMatches(i, j, a, b, len(a)) for i in range(views) for j in range(i + 1, views)
             for _, a, b in [np.intersect1d(ids[i], ids[j], return_indices=True)]]
    K0 = np.array([[700.0, 0, 319.5], [0, 700.0, 239.5], [0, 0, 1]])
    models, _, _ = reconstruct_models(features, pairs, K0, SfMSettings(min_parallax_deg=0.5),
                                      focal=FocalSettings(700.0, 0.5, "prior"))
    focal = models[0].focal
    assert not focal.determined and not focal.trusted and focal.source == "prior"
    assert models[0].K[0, 0] == 700.0 and focal.sigma_px == pytest.approx(350.0)
    assert any("do not determine" in w for w in focal.warnings)


def _run(args, cwd=None):
    return subprocess.run([sys.executable, "-m", "scene3D", "reconstruct-views", *map(str, args)],
                          capture_output=True, text=True, timeout=900, cwd=cwd)


@pytest.fixture(scope="module")
def fountain_no_calib(fountain, tmp_path_factory):
    """reconstruct-views on all 11 fountain images at 1536 px without --calib (the
    Strecha JPEGs carry no EXIF: the focal length starts from 1.2 x 1536, 33 % long)."""
    out = tmp_path_factory.mktemp("views_no_calib")
    proc = _run([fountain / "images", "--ground-truth", fountain / "gt_dense_cameras",
                 "--out", out, "--no-plots", "--no-report"])
    return proc, out


def test_fountain_without_a_calibration(fountain_no_calib, fountain):
    proc, out = fountain_no_calib
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["registered"] == 11 and summary["unregistered"] == []
    assert summary["image_size"] == [1536, 1024]
    truth = read_strecha_camera(fountain / "gt_dense_cameras" / "0000.jpg.camera").K
    f_true = math.sqrt(truth[0, 0] * truth[1, 1]) / 2
    K = np.array(summary["K"])
    assert abs(K[0, 0] / f_true - 1) < 0.01 and K[0, 0] == K[1, 1]
    np.testing.assert_allclose(K[:2, 2], [767.5, 511.5])  # the centre
    assert summary["calibration_source"] == "prior+refined"
    sigma = summary["focal_px_sigma"]
    assert 0 < sigma < 0.01 * K[0, 0]
    assert abs(K[0, 0] - f_true) < 3 * sigma
    cal = summary["self_calibration"]
    assert cal["prior_focal_px"] == pytest.approx(1.2 * 1536) and cal["determined"]
    assert cal["trusted"] and cal["warnings"] == []
    assert len(cal["start_pair"]) == 2
    gt = summary["ground_truth"]
    assert gt["focal_error_fraction"] == pytest.approx(K[0, 0] / f_true - 1)
    # The principal point at the centre (the true one is 0.5 % and 0.8 % off) turns
    # the cameras by about 0.3 deg: ten times the calibrated errors, still small.
    assert gt["max_rotation_error_deg"] < 0.6 and gt["max_center_error_fraction"] < 0.01
    assert summary["reprojection_rmse_px"] < 0.5
    assert "focal length" in proc.stdout and "refined by the photos" in proc.stdout
    # The COLMAP model carries the focal length found, at the photos' size (3072x2048).
    camera_line = next(line for line in (out / "colmap" / "cameras.txt").read_text().splitlines()
                       if not line.startswith("#"))
    assert camera_line.split()[2:4] == ["3072", "2048"]
    assert float(camera_line.split()[4]) == pytest.approx(2 * K[0, 0])


def test_a_few_views_whose_focal_lengths_differ_widen_its_sigma(castle, tmp_path):
    """castle-P19's views 0004-0011 alone: the adjustment's sigma and the principal
    point's share came to 0.02 % (0.3 px) against an error of 0.14 % (7 sigma). The views
    call for focal lengths that differ by more: their spread (a jackknife over the views)
    is part of the sigma, which now covers the error within 2 sigma."""
    photos, truth = tmp_path / "photos", tmp_path / "truth"
    photos.mkdir()
    truth.mkdir()
    for i in range(4, 12):
        name = f"{i:04d}.jpg"
        (photos / name).symlink_to(castle / "images" / name)
        (truth / f"{name}.camera").symlink_to(castle / "gt_dense_cameras" / f"{name}.camera")
    out = tmp_path / "out"
    proc = _run([photos, "--ground-truth", truth, "--out", out, "--no-plots", "--no-report"])
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["registered"] == 8
    cal, error = summary["self_calibration"], summary["ground_truth"]["focal_error_fraction"]
    sigma_log = summary["focal_px_sigma"] / summary["K"][0][0]
    assert abs(error) < 2 * sigma_log
    assert cal["jackknife_sigma_log"] > math.hypot(cal["adjustment_sigma_log"],
                                                   cal["principal_point_sigma_log"])
    assert sigma_log == pytest.approx(math.hypot(cal["adjustment_sigma_log"],
                                                 cal["principal_point_sigma_log"],
                                                 cal["jackknife_sigma_log"]))


def _exif(make, model):
    exif = Image.Exif()
    exif[ExifTags.Base.Make], exif[ExifTags.Base.Model] = make, model
    return exif.tobytes()


@pytest.mark.parametrize("second, message", [
    ({"exif": _exif("Apple", "iPhone 12")}, "one camera is needed with --camera-mode single"),
    ({"size": (300, 200)}, "photos of one camera at one size are needed"),
])
def test_photos_of_two_cameras_are_refused_as_one_camera(tmp_path, second, message):
    """With --camera-mode single the photos must share a camera (by default they are two
    cameras: tests/test_multiview_cameras.py)."""
    rng = np.random.default_rng(0)
    pixels = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
    Image.fromarray(pixels).save(tmp_path / "a.jpg", exif=_exif("Canon", "EOS 5D"))
    b = Image.fromarray(pixels)
    if "size" in second:
        b = b.resize(second["size"])
    b.save(tmp_path / "b.jpg", exif=second.get("exif", _exif("Canon", "EOS 5D")))
    proc = _run([tmp_path / "a.jpg", tmp_path / "b.jpg", "--out", tmp_path / "out",
                 "--camera-mode", "single"])
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not (tmp_path / "out" / "reconstruction.json").exists()


@pytest.fixture(scope="module")
def fountain_with_exif(fountain, tmp_path_factory):
    """Five fountain views re-saved with a 35 mm-equivalent EXIF focal length: 32 mm (the
    true 32.34 mm rounded, as the tag stores it) and 23 mm (29 % short, as a cropped copy
    would carry)."""
    folders = {}
    for focal_35mm in (32, 23):
        folder = tmp_path_factory.mktemp(f"exif{focal_35mm}")
        exif = exif_block({ExifTags.Base.Make: "Canon", ExifTags.Base.Model: "EOS 5D"},
                          {ExifTags.Base.FocalLengthIn35mmFilm: focal_35mm})
        for i in range(3, 8):
            with Image.open(fountain / "images" / f"{i:04d}.jpg") as img:
                img.save(folder / f"{i:04d}.jpg", quality=95, subsampling=0, exif=exif.tobytes())
        folders[focal_35mm] = folder
    return folders


@pytest.mark.parametrize("focal_35mm, trusted", [(32, True), (23, False)])
def test_an_exif_focal_length_is_refined_and_a_wrong_one_overruled(fountain, fountain_with_exif,
                                                                    tmp_path, focal_35mm,
                                                                    trusted):
    out = tmp_path / "out"
    proc = _run([fountain_with_exif[focal_35mm], "--max-width", "800", "--out", out,
                 "--no-plots", "--no-report"])
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["registered"] == 5 and summary["calibration_source"] == "exif+refined"
    cal = summary["self_calibration"]
    assert cal["camera"] == "Canon EOS 5D" and "FocalLengthIn35mmFilm" in cal["start"]
    assert cal["prior_sigma_log"] == pytest.approx(0.03)
    truth = read_strecha_camera(fountain / "gt_dense_cameras" / "0003.jpg.camera").K
    f_true = math.sqrt(truth[0, 0] * truth[1, 1]) / 4  # 3072 -> 768
    assert summary["image_size"] == [768, 512]
    assert abs(summary["K"][0][0] / f_true - 1) < 0.01
    assert cal["trusted"] is trusted
    if not trusted:
        assert any("times the EXIF one" in w for w in cal["warnings"])
        assert "times the EXIF one" in proc.stderr and "untrusted" in proc.stdout


def test_arrays_without_a_calibration_start_from_the_default_prior():
    from scene3D.multiview import reconstruct_views
    from scene3D.multiview.pipeline import default_focal_prior

    prior = default_focal_prior([np.zeros((480, 640, 3), np.uint8)] * 2, ["a", "b"])
    assert prior.source == "prior" and prior.focal_px == pytest.approx(1.2 * 640)
    np.testing.assert_allclose(prior.K[:2, 2], [319.5, 239.5])
    with pytest.raises(ValueError, match="one camera at one size"):
        default_focal_prior([np.zeros((480, 640, 3), np.uint8),
                             np.zeros((400, 640, 3), np.uint8)], ["a", "b"])
    with pytest.raises(ValueError, match="`dist` needs `K`"):
        reconstruct_views([np.zeros((480, 640, 3), np.uint8)] * 2, None, np.zeros(5))


def test_the_start_falls_back_on_a_pair_trusted_under_its_own_focal_length():
    """When the mapper finds no trusted pair under the self-calibrated focal length, a
    self-calibrated pair whose own geometry is trusted starts, with its focal length."""
    from scene3D.multiview.focal import self_calibrated_start

    features, pairs, _, _ = _orbit_views(0.5)
    K0 = np.array([[676.0, 0, 319.5], [0, 676.0, 239.5], [0, 0, 1]])
    settings = FocalSettings(676.0, 0.5, "prior")
    start, K_start, estimate = self_calibrated_start(features, pairs, K0, settings,
                                                     lambda *args: "no trusted pair")
    pair, geometry = start
    assert geometry.trusted and np.array_equal(geometry.K, K_start)
    assert estimate.start_pair == (pair.i, pair.j) and estimate.source == "prior+refined"
    assert K_start[0, 0] == estimate.focal_px == estimate.start_focal_px
    # One pair, the principal point 1.5-2 % off the centre: within its sigma's reach.
    assert abs(np.log(K_start[0, 0] / 520.0)) < 3 * estimate.sigma_px / estimate.focal_px
    best = max(pairs, key=lambda p: p.num_inliers)
    assert pair.num_inliers == best.num_inliers  # the first candidate, trusted


def test_a_wide_focal_sigma_prints_as_a_factor():
    # What reconstruct-views and chapter4.py print after the focal length (one helper).
    from scene3D.cli.common import focal_sigma_text

    assert focal_sigma_text(1000.0, 1.4) == "+-1.4"
    assert focal_sigma_text(1000.0, 500.0) == "(1 sigma: a factor of 1.6)"
