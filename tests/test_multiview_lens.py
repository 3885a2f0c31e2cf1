"""Photos of a distorting lens without a calibration file (scene3D.multiview.lens): a
rendered half orbit photographed through a barrel lens, reconstructed end to end."""

import json
import re
import subprocess
import sys

import cv2
import numpy as np
import pytest

from scene3D.errors import ReconstructionError
from scene3D.evaluation import camera_set_error
from scene3D.evaluation.synthetic import lens_photo, orbit_poses, orbit_scene, render_planes
from scene3D.geometry.lens import max_shift_px
from scene3D.io.colmap import read_colmap_text
from scene3D.multiview import reconstruct_views

K_TRUE = np.array([[560.0, 0, 319.5], [0, 560.0, 239.5], [0, 0, 1]])
K1_TRUE = -0.12
VIEWS = 12


@pytest.fixture(scope="module")
def lens_orbit():
    """Twelve views 15 deg apart around the courtyard, each photo bent by the lens (the
    corners 30 px from where a pinhole camera would put them)."""
    Rs, ts = orbit_poses(2 * VIEWS)
    Rs, ts = Rs[:VIEWS], ts[:VIEWS]
    scene = orbit_scene()
    photos = [lens_photo(render_planes(K_TRUE, R, t, rectangles=scene, supersample=1)[0],
                         K_TRUE, K1_TRUE) for R, t in zip(Rs, ts)]
    return photos, Rs, -np.einsum("vji,vj->vi", Rs, ts)


def _errors(recon, Rs, centers):
    model = recon.main
    err = camera_set_error(model.R, model.centers, Rs, centers)
    return err.rotation_errors_deg.max(), err.center_errors.max()


def test_the_lens_is_found_and_removed(lens_orbit):
    """Without a calibration the default camera (simple_radial) finds the lens: k1 within
    0.01 and the focal length within 1 % of the truth, every view registered, the cameras
    within 0.3 deg; the result's dist is the lens. A pinhole camera gets no start (the
    pairs call for a focal length 0.82 times the prior's) or a worse model."""
    photos, Rs, centers = lens_orbit
    shift = max_shift_px(K_TRUE, [K1_TRUE], (640, 480))
    assert 28 < shift < 33
    recon = reconstruct_views(photos, None, progress=lambda _: None)
    assert recon.camera_model == "simple_radial" and recon.lens_passes >= 1
    assert recon.main.registered.all()
    assert abs(recon.dist[0] - K1_TRUE) < 0.01 and not np.any(recon.dist[1:])
    assert abs(recon.K[0, 0] / K_TRUE[0, 0] - 1) < 0.01
    rotation, center = _errors(recon, Rs, centers)
    assert rotation < 0.3 and center < 0.01

    # The pinhole camera (what every run got before): no pair looks trustworthy under the
    # bent matches, so no start; where one starts, a focal length and cameras further off.
    try:
        pinhole = reconstruct_views(photos, None, camera_model="pinhole",
                                    progress=lambda _: None)
    except ReconstructionError as exc:
        assert exc.reason == "no_initial_pair"
        return
    assert pinhole.camera_model == "pinhole" and pinhole.dist.size == 0
    assert pinhole.lens_passes == 0
    pinhole_rotation, pinhole_center = (_errors(pinhole, Rs, centers)
                                        if pinhole.main.registered.all() else (np.inf, np.inf))
    assert abs(pinhole.K[0, 0] / K_TRUE[0, 0] - 1) > abs(recon.K[0, 0] / K_TRUE[0, 0] - 1)
    assert pinhole_rotation > rotation or pinhole_center > center


def test_the_command_prints_and_writes_the_lens(lens_orbit, tmp_path):
    """``reconstruct-views`` on the photos as files: a line names the lens, the summary
    carries it, and the COLMAP model is SIMPLE_RADIAL with its observations where the
    points lie in the photos as taken (reprojected through that camera, as small an error
    as the model's own)."""
    photos, _, _ = lens_orbit
    folder = tmp_path / "photos"
    folder.mkdir()
    for i, photo in enumerate(photos[:8]):
        cv2.imwrite(str(folder / f"{i:02d}.png"), photo)
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "scene3D", "reconstruct-views", str(folder),
                          "--out", str(out), "--no-plots", "--no-report"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    (line,) = [ln for ln in run.stdout.splitlines() if ln.startswith("lens (simple_radial)")]
    k1 = float(re.search(r"k1 ([-+][0-9.]+)", line).group(1))
    assert abs(k1 - K1_TRUE) < 0.015
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["camera_model"] == "simple_radial"
    assert summary["distortion"][0] == pytest.approx(k1, abs=1e-4)
    colmap = read_colmap_text(out / "colmap")
    (camera,) = colmap.cameras.values()
    assert camera.model == "SIMPLE_RADIAL"
    assert camera.params[3] == pytest.approx(summary["distortion"][0])
    assert np.median(colmap.errors_px) < 2 * summary["reprojection_rmse_px"] + 0.1


@pytest.mark.parametrize("model", ["simple_radial", "radial"])
def test_a_calibration_gives_the_camera(lens_orbit, model):
    photos, _, _ = lens_orbit
    with pytest.raises(ValueError, match="needs photos without a calibration"):
        reconstruct_views(photos[:2], K_TRUE, camera_model=model)


def test_an_unknown_camera_model_is_named(lens_orbit):
    photos, _, _ = lens_orbit
    with pytest.raises(ValueError, match="unknown camera model 'fisheye'"):
        reconstruct_views(photos[:2], None, camera_model="fisheye")
