"""scene3D.io.colmap: COLMAP text models read in scene3D's conventions, written back, and
taken to the photos' size; round trips through our writers and pycolmap's (bench extra)."""

import numpy as np
import pytest

from scene3D.evaluation.synthetic import asymmetric_camera, orbit_poses
from scene3D.geometry.conventions import project
from scene3D.io.colmap import (
    CAMERA_MODELS,
    ColmapCamera,
    ColmapFormatError,
    colmap_model_from_views,
    colmap_text,
    model_for_photos,
    read_colmap_text,
    write_colmap_text,
)
from scene3D.io.export import colmap_text_files, write_text_files


def orbit_views(n_views: int = 6, n_points: int = 80, seed: int = 3):
    """Known cameras on an orbit and points around its centre, each seen by every view:
    ``K`` (fx != fy, off-centre principal point), size, R, t, points, colours, the
    observations (view, point, exact pixel)."""
    K = asymmetric_camera(640, 480)
    R, t = orbit_poses(n_views)
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1.5, 1.5, (n_points, 3))
    colors = rng.integers(0, 256, (n_points, 3)).astype(np.uint8)
    obs_view = np.repeat(np.arange(n_views), n_points)
    obs_point = np.tile(np.arange(n_points), n_views)
    obs_xy = np.concatenate([project(X, K, R[v], t[v]) for v in range(n_views)])
    return K, (640, 480), R, t, X, colors, obs_view, obs_point, obs_xy


def test_a_model_of_some_views_reads_back_in_our_conventions(tmp_path):
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views()
    registered = np.ones(len(R), bool)
    registered[2] = False  # a view in no model: neither in images.txt nor in the tracks
    keep = registered[obs_view]
    write_colmap_text(tmp_path, colmap_model_from_views(
        [f"v{i}.jpg" for i in range(len(R))], K, size, registered, R, t, X, colors,
        obs_view, obs_point, obs_xy))
    model = read_colmap_text(tmp_path)
    assert model.names == ("v0.jpg", "v1.jpg", "v3.jpg", "v4.jpg", "v5.jpg")
    assert list(model.image_ids) == [1, 2, 4, 5, 6]
    camera = model.camera(0)
    assert camera.model == "PINHOLE" and camera.image_size == size
    np.testing.assert_allclose(camera.K, K, atol=1e-9)
    assert camera.dist.size == 0
    views = np.nonzero(registered)[0]
    np.testing.assert_allclose(model.R, R[views], atol=1e-10)
    np.testing.assert_allclose(model.t, t[views], atol=1e-9)
    np.testing.assert_allclose(model.points3d, X, atol=1e-8)
    np.testing.assert_array_equal(model.colors, colors)
    # Every observation, in OpenCV pixels, is its point projected (the half pixel undone).
    np.testing.assert_allclose(model.reprojection_errors_px(), 0, atol=2e-6)
    assert len(model.obs_view) == keep.sum()


def test_the_old_writer_warns_naming_its_replacement_and_writes_the_same_model(tmp_path):
    """``scene3D.io.export.colmap_text_files`` (deprecated) still gives the model the new
    writer gives, to its own precision, and its warning names the new writer."""
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views()
    registered = np.ones(len(R), bool)
    registered[2] = False
    keep = registered[obs_view]
    names = [f"v{i}.jpg" for i in range(len(R))]
    with pytest.warns(DeprecationWarning, match=r"use scene3D\.io\.colmap\.colmap_text\("):
        files = colmap_text_files(names, K, size, registered, R, t, X, colors, obs_view[keep],
                                  obs_point[keep], obs_xy[keep], np.zeros(len(X)))
    write_text_files(tmp_path / "old", files)
    old = read_colmap_text(tmp_path / "old")
    write_colmap_text(tmp_path / "new", colmap_model_from_views(
        names, K, size, registered, R, t, X, colors, obs_view, obs_point, obs_xy))
    new = read_colmap_text(tmp_path / "new")
    assert old.names == new.names and old.cameras.keys() == new.cameras.keys()
    np.testing.assert_allclose(old.camera(0).K, new.camera(0).K, atol=1e-9)
    for name in ("R", "t", "points3d", "obs_xy"):
        np.testing.assert_allclose(getattr(old, name), getattr(new, name), rtol=0, atol=1e-6,
                                   err_msg=name)
    for name in ("image_ids", "point_ids", "colors", "obs_view", "obs_point"):
        np.testing.assert_array_equal(getattr(old, name), getattr(new, name), err_msg=name)


def test_our_full_precision_writer_and_reader_round_trip_exactly(tmp_path):
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views()
    model = colmap_model_from_views([f"v{i}.jpg" for i in range(len(R))], K, size,
                                    np.ones(len(R), bool), R, t, X, colors, obs_view,
                                    obs_point, obs_xy)
    np.testing.assert_allclose(model.errors_px, 0, atol=1e-9)
    write_colmap_text(tmp_path, model)
    back = read_colmap_text(tmp_path)
    assert back.cameras == model.cameras and back.names == model.names
    for name in ("R", "t", "points3d", "obs_xy"):
        np.testing.assert_allclose(getattr(back, name), getattr(model, name), rtol=0,
                                   atol=1e-12, err_msg=name)
    for name in ("image_ids", "camera_ids", "point_ids", "colors", "obs_view", "obs_point"):
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name), err_msg=name)
    # Written again, the points and cameras are the same text (rotations differ in the last
    # digit: quaternion to matrix and back).
    again, first = colmap_text(back), colmap_text(model)
    assert again["cameras.txt"] == first["cameras.txt"]
    assert again["points3D.txt"] == first["points3D.txt"]


@pytest.mark.parametrize("name, params, dist", [
    ("SIMPLE_PINHOLE", (500.0, 320.5, 240.5), []),
    ("PINHOLE", (500.0, 490.0, 320.5, 240.5), []),
    ("SIMPLE_RADIAL", (500.0, 320.5, 240.5, -0.1), [-0.1, 0, 0, 0]),
    ("RADIAL", (500.0, 320.5, 240.5, -0.1, 0.02), [-0.1, 0.02, 0, 0]),
    ("OPENCV", (500.0, 490.0, 320.5, 240.5, -0.1, 0.02, 1e-3, -2e-3),
     [-0.1, 0.02, 1e-3, -2e-3]),
])
def test_each_camera_model_gives_opencv_K_and_distortion(tmp_path, name, params, dist):
    (tmp_path / "cameras.txt").write_text(
        f"# a comment\n7 {name} 640 480 {' '.join(map(str, params))}\n")
    (tmp_path / "images.txt").write_text("")
    (tmp_path / "points3D.txt").write_text("")
    camera = read_colmap_text(tmp_path).cameras[7]
    f = params[0]
    fy = params[1] if name in ("PINHOLE", "OPENCV") else f
    cx, cy = params[2:4] if name in ("PINHOLE", "OPENCV") else params[1:3]
    np.testing.assert_allclose(camera.K, [[f, 0, cx - 0.5], [0, fy, cy - 0.5], [0, 0, 1]])
    np.testing.assert_allclose(camera.dist, dist)
    assert set(CAMERA_MODELS) >= {name}


def test_an_unknown_camera_model_names_the_model_and_the_file(tmp_path):
    (tmp_path / "cameras.txt").write_text("1 OPENCV_FISHEYE 640 480 500 500 320 240 0 0 0 0\n")
    (tmp_path / "images.txt").write_text("")
    (tmp_path / "points3D.txt").write_text("")
    with pytest.raises(ColmapFormatError, match="OPENCV_FISHEYE") as info:
        read_colmap_text(tmp_path)
    assert str(tmp_path / "cameras.txt") in str(info.value)
    assert "line 1" in str(info.value)


def test_a_missing_file_and_a_bad_track_are_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="cameras.txt"):
        read_colmap_text(tmp_path)
    (tmp_path / "cameras.txt").write_text("1 PINHOLE 640 480 500 500 320 240\n")
    (tmp_path / "images.txt").write_text("1 1 0 0 0 0 0 0 1 a.jpg\n10 20 1\n")
    (tmp_path / "points3D.txt").write_text("1 0 0 5 255 0 0 0.1 1 0 2 0\n")
    with pytest.raises(ColmapFormatError, match="image 2, which images.txt does not list"):
        read_colmap_text(tmp_path)


def test_an_image_without_points_keeps_its_blank_line(tmp_path):
    (tmp_path / "cameras.txt").write_text("1 PINHOLE 640 480 500 500 320 240\n")
    (tmp_path / "images.txt").write_text(
        "# header\n1 1 0 0 0 0 0 0 1 a.jpg\n\n2 1 0 0 0 1 0 0 1 b.jpg\n10.5 20.5 1\n")
    (tmp_path / "points3D.txt").write_text("1 0 0 5 255 0 0 0.1 2 0\n")
    model = read_colmap_text(tmp_path)
    assert model.names == ("a.jpg", "b.jpg")
    np.testing.assert_allclose(model.obs_xy, [[10.0, 20.0]])
    np.testing.assert_array_equal(model.obs_view, [1])
    np.testing.assert_allclose(model.centers[1], [-1, 0, 0])


def test_the_model_at_the_photos_size_with_their_distortion_projects_exactly():
    """Working images at half size, undistorted: the photos' camera has K scaled back and
    the lens's distortion, and the observations are where the points fall in the photos."""
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views()
    working = colmap_model_from_views([f"v{i}.jpg" for i in range(len(R))], K, size,
                                      np.ones(len(R), bool), R, t, X, colors, obs_view,
                                      obs_point, obs_xy)
    dist = np.array([-0.12, 0.03, 4e-4, -6e-4])
    photos = model_for_photos(working, (1280, 960), dist)
    camera = photos.camera(0)
    assert camera.model == "OPENCV" and camera.image_size == (1280, 960)
    K_photo = camera.K
    np.testing.assert_allclose(K_photo[[0, 1], [0, 1]], 2 * K[[0, 1], [0, 1]])
    np.testing.assert_allclose(K_photo[:2, 2], 2 * (K[:2, 2] + 0.5) - 0.5)
    np.testing.assert_allclose(camera.dist, dist)
    np.testing.assert_allclose(photos.reprojection_errors_px(), 0, atol=1e-6)
    np.testing.assert_allclose(photos.errors_px, 0, atol=1e-6)
    # Distortion moves the observations away from the pinhole projection.
    pinhole = model_for_photos(working, (1280, 960))
    assert pinhole.camera(0).model == "PINHOLE"
    assert np.abs(photos.obs_xy - pinhole.obs_xy).max() > 1.0
    with pytest.raises(ValueError, match="aspect ratio"):
        model_for_photos(working, (1280, 720))


def test_from_opencv_refuses_what_colmap_cannot_hold():
    K = asymmetric_camera()
    assert ColmapCamera.from_opencv(K, [0, 0, 0, 0, 0.01], (640, 480)).model == "FULL_OPENCV"
    with pytest.raises(ValueError, match="thin-prism"):
        ColmapCamera.from_opencv(K, [0] * 8 + [0.01, 0, 0, 0], (640, 480))


def pycolmap_reconstruction(pycolmap, K, R, t, X, colors):
    """A pycolmap model of the orbit: two cameras (PINHOLE and OPENCV with distortion,
    COLMAP's pixels OpenCV's + 0.5) taking turns, every point seen by every image at its
    exact projection, the errors pycolmap's."""
    rec = pycolmap.Reconstruction()
    cams = [pycolmap.Camera(model="PINHOLE", width=640, height=480,
                            params=[K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5],
                            camera_id=1),
            pycolmap.Camera(model="OPENCV", width=640, height=480,
                            params=[K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5,
                                    -0.1, 0.02, 1e-3, -2e-3], camera_id=2)]
    for cam in cams:
        rec.add_camera_with_trivial_rig(cam)
    for v in range(len(R)):
        camera = cams[v % 2]
        cam_from_world = pycolmap.Rigid3d(pycolmap.Rotation3d(R[v]), t[v])
        points2d = [pycolmap.Point2D(camera.img_from_cam(R[v] @ x + t[v]))
                    for x in X]
        image = pycolmap.Image(name=f"img {v}.jpg".replace(" ", "_"), points2D=points2d,
                               camera_id=camera.camera_id, image_id=v + 1)
        rec.add_image_with_trivial_frame(image, cam_from_world)
    for p, x in enumerate(X):
        track = pycolmap.Track()
        for v in range(len(R)):
            track.add_element(v + 1, p)
        rec.add_point3D(x, track, colors[p])
    rec.update_point_3d_errors()
    return rec


def test_a_model_written_by_pycolmap_reads_back_with_its_cameras_and_points(tmp_path):
    pycolmap = pytest.importorskip("pycolmap")
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views(n_views=4)
    pycolmap_reconstruction(pycolmap, K, R, t, X, colors).write_text(str(tmp_path))

    model = read_colmap_text(tmp_path)
    assert model.names == tuple(f"img_{v}.jpg" for v in range(len(R)))
    np.testing.assert_allclose(model.camera(0).K, K, atol=1e-9)
    np.testing.assert_allclose(model.camera(1).K, K, atol=1e-9)
    assert model.camera(1).model == "OPENCV"
    np.testing.assert_allclose(model.camera(1).dist, [-0.1, 0.02, 1e-3, -2e-3])
    np.testing.assert_allclose(model.R, R, atol=1e-9)
    np.testing.assert_allclose(model.t, t, atol=1e-9)
    order = np.argsort(model.point_ids)
    np.testing.assert_allclose(model.points3d[order], X, atol=1e-9)
    np.testing.assert_array_equal(model.colors[order], colors)
    # Our projection with the camera read back (distortion included) meets pycolmap's 2D
    # points to well under a pixel, and its errors are ours.
    np.testing.assert_allclose(model.reprojection_errors_px(), 0, atol=1e-6)
    np.testing.assert_allclose(model.errors_px, 0, atol=1e-6)


def test_a_pycolmap_model_reads_as_pycolmap_reads_it_and_its_report_opens(tmp_path, capsys):
    """The text model pycolmap writes (with its rigs.txt and frames.txt), read by scene3D, has the
    cameras, poses, points and tracks pycolmap reads from it; ``scene3d report`` on it
    opens in headless Chromium with no console error, offline, and a 3D view whose clouds
    cover part of the canvas."""
    pycolmap = pytest.importorskip("pycolmap")
    from scene3D.cli.report import main as report

    from .browser import changed_fraction, visit

    K, size, R, t, X, colors, *_ = orbit_views(n_views=4, n_points=400)  # enough to see
    pycolmap_reconstruction(pycolmap, K, R, t, X, colors).write_text(str(tmp_path))
    theirs = pycolmap.Reconstruction(str(tmp_path))
    ours = read_colmap_text(tmp_path)

    assert sorted(ours.cameras) == sorted(theirs.cameras)
    for cam_id, camera in theirs.cameras.items():
        mine = ours.cameras[cam_id]
        assert (mine.model, mine.width, mine.height) == (camera.model.name, camera.width,
                                                         camera.height)
        np.testing.assert_allclose(mine.params, camera.params, rtol=1e-12)
        np.testing.assert_allclose(mine.K, camera.calibration_matrix() - np.array(
            [[0, 0, 0.5], [0, 0, 0.5], [0, 0, 0]]), atol=1e-9)  # OpenCV's centres
    assert list(ours.image_ids) == sorted(theirs.images)
    view_of = {image_id: v for v, image_id in enumerate(ours.image_ids)}
    for image_id, image in theirs.images.items():
        v = view_of[image_id]
        pose = image.cam_from_world()
        assert ours.names[v] == image.name and ours.camera_ids[v] == image.camera_id
        np.testing.assert_allclose(ours.R[v], pose.rotation.matrix(), atol=1e-12)
        np.testing.assert_allclose(ours.t[v], pose.translation, atol=1e-12)
        np.testing.assert_allclose(ours.centers[v], image.projection_center(), atol=1e-9)
    index_of = {point_id: p for p, point_id in enumerate(ours.point_ids)}
    assert sorted(index_of) == sorted(theirs.points3D)
    for point_id, point in theirs.points3D.items():
        p = index_of[point_id]
        np.testing.assert_allclose(ours.points3d[p], point.xyz, atol=1e-12)
        np.testing.assert_array_equal(ours.colors[p], point.color)
        assert ours.errors_px[p] == pytest.approx(point.error, abs=1e-9)
        # Each element of its track is an observation of ours, at pycolmap's 2D point
        # with the half pixel undone.
        for element in point.track.elements:
            v = view_of[element.image_id]
            k = np.flatnonzero((ours.obs_view == v) & (ours.obs_point == p))
            assert len(k) == 1
            xy = theirs.images[element.image_id].points2D[element.point2D_idx].xy
            np.testing.assert_allclose(ours.obs_xy[k[0]], np.asarray(xy) - 0.5, atol=1e-9)
    assert len(ours.obs_view) == sum(len(p.track.elements) for p in theirs.points3D.values())

    assert report([str(tmp_path)]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"4 images, {len(X)} points, 2 cameras", f"Wrote '{tmp_path / 'report.html'}'"]
    page = visit(tmp_path / "report.html", wait_for_view=True)
    assert page.errors == [], page.errors
    assert page.requests and page.outside_requests == [], page.requests
    # The points cover part of the WebGL canvas (hiding them changes those pixels), and a
    # drag turns the scene.
    assert changed_fraction(page.canvas_after_drag, page.canvas_without_clouds) > 0.003
    assert "scene.camera" in page.relayout_keys
    assert f"{len(X)} points (plotly.js" in page.text and "640 x 480 px" in page.text
