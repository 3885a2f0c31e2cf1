import csv
import re

import numpy as np
import pytest

from scene3D.cli.evaluate import main
from scene3D.evaluation import (
    camera_set_error,
    paired_auc_difference,
    pose_auc,
    relative_pose_error,
    sigma_calibration,
    summarize_pose_errors,
)
from scene3D.geometry import rotation_about_axis


def test_pose_errors_of_a_known_perturbation():
    R = rotation_about_axis([0, 1, 0], 10)
    err = relative_pose_error(rotation_about_axis([1, 0, 0], 2) @ R, [0, 0, 2], R, [0, 0, 5])
    assert err.rotation_deg == pytest.approx(2.0)
    assert err.translation_deg == pytest.approx(0.0, abs=1e-6)  # scale does not matter
    assert relative_pose_error(R, [0, 0, -1], R, [0, 0, 1]).translation_deg == pytest.approx(180)


def _cameras_on_a_line():
    """Five views along the world x axis (centres slightly off it), oblique orientations."""
    centers = np.array([[-2.0, 0.01, 0.0], [-0.7, 0.0, 0.02], [0.4, -0.01, 0.0],
                        [1.5, 0.0, -0.01], [3.1, 0.02, 0.01]])
    R = np.array([rotation_about_axis([0.2, 1, 0.1], a) @ rotation_about_axis([1, 0, 0.3], 7)
                  for a in (-20, -8, 3, 15, 31)])
    return R, centers


def test_camera_set_error_both_alignments_undo_a_similarity():
    R, centers = _cameras_on_a_line()
    A, s, b = rotation_about_axis([0.3, -0.5, 1], 40), 2.5, np.array([1.0, -3.0, 0.5])
    # X_est = A^T (X_true - b) / s: centres map likewise, orientations as R_est = R_true A.
    c_est = (centers - b) @ A / s
    for align in ("orientations", "centres"):
        err = camera_set_error(R @ A, c_est, R, centers, align=align)
        np.testing.assert_allclose(err.center_errors, 0.0, atol=1e-12)
        np.testing.assert_allclose(err.rotation_errors_deg, 0.0, atol=1e-6)
    with pytest.raises(ValueError, match="align"):
        camera_set_error(R, centers, R, centers, align="points")


def test_camera_set_error_roll_about_the_line_only_orientations_see():
    """The world turned 0.5 deg about the line of centres: both alignments undo it while
    the centres are exact; once the centres carry noise, the centre alignment's roll
    follows the noise (the centres hardly constrain it) and every rotation error carries
    it, while the orientation alignment still undoes the turn."""
    R, centers = _cameras_on_a_line()
    roll = rotation_about_axis([1, 0, 0], 0.5)
    c_est = centers @ roll  # the world turned about x: R_est = R roll, C_est = roll^T C
    by_orientations = camera_set_error(R @ roll, c_est, R, centers)
    by_centres = camera_set_error(R @ roll, c_est, R, centers, align="centres")
    np.testing.assert_allclose(by_orientations.rotation_errors_deg, 0.0, atol=1e-6)
    np.testing.assert_allclose(by_orientations.center_errors, 0.0, atol=1e-12)
    np.testing.assert_allclose(by_centres.center_errors, 0.0, atol=1e-12)
    np.testing.assert_allclose(by_centres.rotation_errors_deg, 0.0, atol=1e-6)
    # Now the centres move off the line by noise: the centre alignment follows the noise
    # in its roll, the orientation alignment does not.
    rng = np.random.default_rng(3)
    noisy = c_est + rng.normal(scale=0.005, size=c_est.shape)
    by_orientations = camera_set_error(R @ roll, noisy, R, centers)
    by_centres = camera_set_error(R @ roll, noisy, R, centers, align="centres")
    assert by_orientations.rotation_errors_deg.max() < 1e-6
    assert by_centres.rotation_errors_deg.min() > 0.05
    assert by_centres.center_errors.max() <= by_orientations.center_errors.max()


def test_auc_and_summary():
    assert pose_auc([0.0, 0.0]) == pytest.approx(100.0)
    assert pose_auc([np.inf, np.inf]) == pytest.approx(0.0)
    # Errors 1 and 3 deg: recall 0.5 on [1, 3) and 1 on [3, 5) -> (0.5 * 2 + 1 * 2) / 5.
    assert pose_auc([1.0, 3.0]) == pytest.approx(60.0)
    stats = summarize_pose_errors([0.1, 1.0, 9.0, np.inf], [0.2, 3.0, 0.1, np.inf],
                                  flagged=[False, False, False, True])
    assert stats["within_2deg"] == 0.25 and stats["within_5deg"] == 0.5
    assert stats["wrong_unflagged"] == 1  # the 9 deg pair; the failed one was flagged
    assert stats["right_flagged"] == 0 and stats["off2"] == 3 and stats["off2_flagged"] == 1
    flags = summarize_pose_errors([0.1, 0.5, 3.0], [0.1, 0.2, 0.1], [True, False, True])
    assert flags["right_flagged"] == 1 and flags["off2_flagged"] == flags["off2"] == 1


def test_sigma_calibration_counts_errors_within_the_90_percent_bounds():
    # Chi-square 3 and 2 dof: 6.25 and 4.61 bound 90 %; NaN (no pose) is left out.
    calib = sigma_calibration([1.0, 7.0, 2.0, np.nan], [5.0, 1.0, 4.0, 0.1])
    assert calib["pairs"] == 3
    assert calib["rotation_within90"] == pytest.approx(2 / 3)
    assert calib["translation_within90"] == pytest.approx(2 / 3)
    rng = np.random.default_rng(0)  # calibrated Gaussian errors: about 90 %
    calib = sigma_calibration(np.sum(rng.normal(size=(4000, 3)) ** 2, axis=1),
                              np.sum(rng.normal(size=(4000, 2)) ** 2, axis=1))
    assert calib["rotation_within90"] == pytest.approx(0.9, abs=0.015)
    assert calib["translation_within90"] == pytest.approx(0.9, abs=0.015)


def test_evaluate_command_on_fountain(fountain, tmp_path, capsys):
    csv_path = tmp_path / "rows.csv"
    csv_path.write_text("an earlier run's rows")  # replaced: --force
    code = main([str(fountain), "--pairs", "4-5", "2-4", "--csv", str(csv_path), "--force",
                 "-q"])
    out = capsys.readouterr().out
    assert code == 0
    assert "| 0004.jpg-0005.jpg |" in out and "| 0002.jpg-0004.jpg |" in out
    assert "2 pairs at 768 px" in out and "wrong and unflagged 0" in out
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["pair"] for r in rows] == ["0004.jpg-0005.jpg", "0002.jpg-0004.jpg"]
    for r in rows:
        assert r["width"] == "768" and r["flagged"] == "False"
        assert float(r["rotation_deg"]) < 1.0 and float(r["translation_deg"]) < 3.0
        assert abs(float(r["focal_scale"]) - 1.0) < 0.05  # the Strecha K fits the photos
        assert 0 < float(r["rotation_sigma_deg"]) < 0.1
        assert 0 < float(r["translation_sigma_deg"]) < 0.2
        assert float(r["rotation_chi2"]) >= 0 and float(r["translation_chi2"]) >= 0
    assert "| rotation sigma (deg) | t-dir sigma (deg) |" in out
    assert "Trust: 0 right poses (< 1 deg) flagged; 0 of 0 poses more than 2 deg" in out
    assert re.search(r"Sigma calibration: \d+% of the rotation errors and \d+% of the "
                     r"translation-direction errors within their predicted 90 % bounds \(2 "
                     r"poses", out)
    median_focal = float(re.search(r"focal length: median ([0-9.]+) times", out).group(1))
    assert abs(median_focal - 1.0) < 0.05


def test_evaluate_summary_counts_one_pose_in_the_singular(fountain, capsys):
    assert main([str(fountain), "--pairs", "4-5", "-q"]) == 0
    out = capsys.readouterr().out
    assert "\n1 pair at 768 px" in out and "90 % bounds (1 pose; about 90 %" in out
    assert "1 poses" not in out


@pytest.mark.parametrize("counts, line", [
    ({"right_flagged": 1, "off2_flagged": 0, "off2": 1, "wrong_unflagged": 0},
     "Trust: 1 right pose (< 1 deg) flagged; 0 of 1 pose more than 2 deg off (or refused) "
     "flagged; 0 more than 5 deg off not flagged."),
    ({"right_flagged": 0, "off2_flagged": 2, "off2": 3, "wrong_unflagged": 1},
     "Trust: 0 right poses (< 1 deg) flagged; 2 of 3 poses more than 2 deg off (or refused) "
     "flagged; 1 more than 5 deg off not flagged."),
])
def test_evaluate_trust_line_says_pose_for_one(counts, line):
    from scene3D.evaluation.pairs import trust_line

    assert trust_line(counts) == line


def test_evaluate_refuses_a_pair_of_two_cameras(fountain, tmp_path, capsys):
    # The same two photos, but the second view's camera file claims another focal length:
    # one K for both would be a silent wrong answer, so the pair is refused and flagged.
    for sub in ("images", "gt_dense_cameras"):
        (tmp_path / sub).mkdir()
    for name in ("0004.jpg", "0005.jpg"):
        (tmp_path / "images" / name).symlink_to(fountain / "images" / name)
        text = (fountain / "gt_dense_cameras" / f"{name}.camera").read_text()
        if name == "0005.jpg":
            text = text.replace("2759.48", "2900", 1)
        (tmp_path / "gt_dense_cameras" / f"{name}.camera").write_text(text)
    assert main([str(tmp_path), "-q"]) == 0
    out = capsys.readouterr().out
    assert "| 0004.jpg-0005.jpg | inf | inf | - | - | 0 | 0 | - | no |" in out
    assert "refused: the two views have different intrinsics" in out
    assert "flagged 1, wrong and unflagged 0" in out


def test_evaluate_maps_one_task_per_view_and_one_per_pair(fountain):
    from scene3D.engines import LocalEngine
    from scene3D.evaluation.pairs import evaluate_pairs
    from scene3D.io.datasets import read_strecha_camera, strecha_views
    from scene3D.twoview import TwoViewSettings

    class Recording(LocalEngine):
        def __init__(self):
            self.tasks, self.shared = [], []

        def map(self, fn, arguments, *, label="tasks", progress=None):
            arguments = list(arguments)
            self.tasks.append((label, len(arguments)))
            return super().map(fn, arguments, label=label, progress=progress)

        def share(self, value):
            self.shared.append(value)
            return value

    views = strecha_views(fountain)[:4]
    engine, seen = Recording(), []
    rows = list(evaluate_pairs(engine, [image for image, _ in views],
                               [read_strecha_camera(c) for _, c in views],
                               [(0, 1), (0, 2), (2, 0)], 400, "SIFT", TwoViewSettings(),
                               lambda label, done, total: seen.append((label, done, total))))
    # Views 0, 1, 2 once each (view 3 is in no pair, view 0 in three), then the pairs.
    assert engine.tasks == [("views", 3), ("pairs", 3)]
    assert len(engine.shared) == 3 and all(v.features.feature == "SIFT" for v in engine.shared)
    assert [r["pair"] for r in rows] == ["0000.jpg-0001.jpg", "0000.jpg-0002.jpg",
                                         "0002.jpg-0000.jpg"]
    assert seen[-1] == ("pairs", 3, 3) and ("views", 3, 3) in seen
    for row in rows:  # each pair (the last one reversed) against the truth
        assert row["inliers"] > 40 and row["rotation_deg"] < 1.0


def test_evaluate_names_the_detector_that_ran(fountain, capsys):
    assert main([str(fountain), "--pairs", "4-5", "--feature", "surf", "-q"]) == 0
    out = capsys.readouterr().out
    # SURF is not in the pip wheels: the summary says what actually ran.
    assert "1 pair at 768 px, SIFT:" in out or "1 pair at 768 px, SURF:" in out


def test_evaluate_bundle_adjusts_when_asked(fountain, capsys, monkeypatch):
    from scene3D.twoview import core as twoview

    calls = []
    adjust = twoview.bundle_adjust_two_view
    monkeypatch.setattr(twoview, "bundle_adjust_two_view",
                        lambda *a, **k: calls.append(len(a[2])) or adjust(*a, **k))
    assert main([str(fountain), "--pairs", "4-5", "-q"]) == 0
    assert calls == []
    assert main([str(fountain), "--pairs", "4-5", "--bundle-adjust", "-q"]) == 0
    assert len(calls) == 1 and calls[0] > 500  # the pair's triangulated points
    assert "wrong and unflagged 0" in capsys.readouterr().out


def test_evaluate_pair_specs():
    from scene3D.evaluation.pairs import pairs_from_specs

    assert pairs_from_specs(["consecutive"], 4) == [(0, 1), (1, 2), (2, 3)]
    assert pairs_from_specs(["skip1"], 4) == [(0, 2), (1, 3)]
    assert pairs_from_specs(["skip4", "1-0"], 11) == [(i, i + 5) for i in range(6)] + [(1, 0)]


@pytest.mark.parametrize("argv, message", [
    (["{tmp}"], "needs images/ and gt_dense_cameras/"),
    (["{fountain}", "--pairs", "3-99"], "out of range"),
    (["{fountain}", "--pairs", "3-3"], "pairs an image with itself"),
    (["{fountain}", "--pairs", "first"], "bad pair 'first'"),
    (["{fountain}", "--pairs", "skip10"], "no image pairs"),
    (["{fountain}", "--csv", "{tmp}/kept.csv"], "kept.csv' exists; use --force"),
    (["{fountain}", "--csv", "{tmp}"], "is a folder"),
    (["{fountain}", "--csv", "{tmp}/no/rows.csv"], "does not exist"),
    (["{fountain}", "--csv", "{tmp}/kept.csv/rows.csv"], "is a file, not a folder"),
    (["{tmp}/nope"], "scene folder not found"),
    (["{fountain}", "--csv", "-"], "--csv '-': give a file name"),
])
def test_evaluate_bad_input(fountain, tmp_path, capsys, argv, message):
    argv = [a.format(tmp=tmp_path, fountain=fountain) for a in argv]
    (tmp_path / "kept.csv").write_text("the user's rows")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert (tmp_path / "kept.csv").read_text() == "the user's rows"


def test_evaluate_progress_lines_name_each_pair_without_trailing_space(fountain, capsys):
    assert main([str(fountain), "--pairs", "4-5"]) == 0
    err = capsys.readouterr().err
    (line,) = [line for line in err.splitlines() if line.startswith("0004.jpg-0005.jpg: ")]
    assert re.fullmatch(r"0004.jpg-0005.jpg: rot [0-9.]+ deg, t-dir [0-9.]+ deg, \d+ inliers, "
                        r"[0-9.]+ s", line)


def test_paired_auc_difference_is_the_auc_difference_with_an_interval():
    rng = np.random.default_rng(2)
    a = rng.uniform(0.0, 1.0, 40)
    b = a + rng.uniform(0.5, 1.5, 40)  # b is worse on every pair
    b[3] = np.inf  # a failed pair
    diff, low, high = paired_auc_difference(a, b)
    assert diff == pytest.approx(pose_auc(a) - pose_auc(b), abs=1e-9)
    assert 0.0 < low < diff < high
    assert paired_auc_difference(a, a) == (0.0, 0.0, 0.0)
    # Two methods that trade small wins pair by pair: the interval straddles zero.
    c = a.copy()
    c[::2] += 0.05
    c[1::2] -= 0.05
    _, low, high = paired_auc_difference(np.abs(c), a)
    assert low < 0.0 < high
    with pytest.raises(ValueError, match="equally shaped"):
        paired_auc_difference(a, a[:-1])
    # Repeated draws of each pair are resampled together: three identical draws per pair
    # say no more than one, whereas taken as 120 independent pairs they would narrow
    # the interval.
    a3, b3 = np.repeat(a[:, None], 3, axis=1), np.repeat(b[:, None], 3, axis=1)
    by_pair = paired_auc_difference(a3, b3)
    assert by_pair == pytest.approx(paired_auc_difference(a, b))
    _, low_flat, high_flat = paired_auc_difference(a3.ravel(), b3.ravel())
    assert high_flat - low_flat < 0.7 * (by_pair[2] - by_pair[1])
