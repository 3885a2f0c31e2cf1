"""Multi-view dense reconstruction (scene3D.densify) against exact geometry: the rendered
courtyard's exact depth, its rectangles, and closed forms; the dense-views command's
files, exit codes and one-line errors."""

import json

import cv2
import numpy as np
import pytest

from scene3D.cli import dense_views
from scene3D.densify import (
    DenseInputError,
    DenseSettings,
    ViewDepth,
    choose_neighbours,
    densify,
    depth_preview,
    depth_range,
    fuse_depth_maps,
    image_paths,
    load_sparse_model,
    neighbour_scores,
    plane_sweep_depth,
    voxel_thin,
)
from scene3D.densify.fusion import depth_normals
from scene3D.densify.views import angle_weight
from scene3D.evaluation.dense import (
    rectangle_distances,
    render_orbit_views,
    score_dense_cloud,
    within_distance,
)
from scene3D.evaluation.synthetic import Rectangle
from scene3D.io.colmap import colmap_model_from_views, write_colmap_text
from scene3D.io.colmap_binary import write_colmap_binary
from scene3D.io.colmap_model import ColmapFormatError
from scene3D.io.export import read_ply, read_ply_normals

SIZE = (320, 240)


def _write_scene(folder, scene, views=None):
    """The rendered views as PNGs in ``folder`` and their exact cameras with the sparse
    points as a COLMAP text model in ``folder/model``; the model's path."""
    views = range(len(scene.images)) if views is None else views
    names = [f"view{k:02d}.png" for k in range(len(scene.images))]
    folder.mkdir(parents=True, exist_ok=True)
    for k in views:
        cv2.imwrite(str(folder / names[k]), scene.images[k])
    registered = np.isin(np.arange(len(names)), list(views))
    h, w = scene.images[0].shape[:2]
    model = colmap_model_from_views(
        names, scene.K, (w, h), registered, scene.R, scene.t, scene.sparse_points,
        np.full((len(scene.sparse_points), 3), 128, np.uint8), scene.obs_view,
        scene.obs_point, scene.obs_xy)
    write_colmap_text(folder / "model", model)
    return folder / "model"


@pytest.fixture(scope="module")
def orbit():
    """Eight views 7.5 degrees apart of the courtyard, with exact depth."""
    return render_orbit_views(8, size=SIZE, arc_deg=60.0)


@pytest.fixture(scope="module")
def orbit_model(orbit, tmp_path_factory):
    return _write_scene(tmp_path_factory.mktemp("orbit"), orbit)


@pytest.fixture(scope="module")
def dense_orbit(orbit_model):
    model = load_sparse_model(orbit_model)
    return densify(model, image_paths(model, orbit_model.parent), DenseSettings(max_width=None))


def _extent(scene):
    return float(np.ptp(scene.surface_samples(), axis=0).max())


# -- neighbours and ranges -----------------------------------------------------------------

def test_angle_weight_is_one_at_five_degrees_and_falls_faster_below():
    w = angle_weight([5.0, 4.0, 6.0, 15.0])
    np.testing.assert_allclose(w, [1.0, np.exp(-0.5), np.exp(-0.005), np.exp(-0.5)])


def test_choose_neighbours_takes_the_best_and_drops_the_weak():
    scores = np.array([[0, 10, 3, 0.1], [10, 0, 5, 1], [3, 5, 0, 2], [0.1, 1, 2, 0]], float)
    assert choose_neighbours(scores, 2) == [[1, 2], [0, 2], [1, 0], [2, 1]]
    assert choose_neighbours(scores, 3)[0] == [1, 2]  # 0.1 < 5 % of 10


def test_neighbours_are_the_nearest_views_of_the_orbit(orbit_model):
    model = load_sparse_model(orbit_model)
    chosen = choose_neighbours(neighbour_scores(model), 2)
    for v, nb in enumerate(chosen):  # cameras 7.5 degrees apart: the next ones
        assert set(nb) <= {v - 2, v - 1, v + 1, v + 2}, (v, nb)


def test_depth_range_holds_the_true_depths_seen(orbit, orbit_model):
    model = load_sparse_model(orbit_model)
    for v in range(len(orbit.images)):
        near, far = depth_range(model, v)
        true = orbit.depths[v][np.isfinite(orbit.depths[v])]
        assert 0 < near < far
        assert near <= np.percentile(true, 1) and far >= np.percentile(true, 95), v


# -- depth maps ---------------------------------------------------------------------------

def test_plane_sweep_depth_matches_the_exact_depth(orbit):
    grey = [cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) for img in orbit.images]
    ref = 3
    neighbours = []
    for j in (2, 4, 1, 5):
        R = orbit.R[j] @ orbit.R[ref].T
        neighbours.append((grey[j], orbit.K, R, orbit.t[j] - R @ orbit.t[ref]))
    depth, ncc = plane_sweep_depth(grey[ref], orbit.K, neighbours, (3.0, 50.0))
    true = orbit.depths[ref]
    valid = np.isfinite(depth) & np.isfinite(true)
    rel = np.abs(depth[valid] - true[valid]) / true[valid]
    assert valid.sum() > 0.8 * np.isfinite(true).sum()
    assert np.median(rel) < 0.005
    assert np.mean(rel < 0.02) > 0.85
    assert np.all(ncc[valid] >= 0.6)


def test_plane_sweep_refuses_an_empty_range():
    img = np.zeros((40, 40), np.uint8)
    with pytest.raises(ValueError, match="depth_range"):
        plane_sweep_depth(img, np.eye(3), [(img, np.eye(3), np.eye(3), np.ones(3))], (5, 2))
    with pytest.raises(ValueError, match="neighbours"):
        plane_sweep_depth(img, np.eye(3), [], (1, 2))


def test_normals_of_a_plane_are_its_normal_towards_the_camera():
    K = np.array([[300.0, 0, 80], [0, 320, 60], [0, 0, 1]])
    n = np.array([0.2, -0.3, -1.0])
    n /= np.linalg.norm(n)
    ys, xs = np.mgrid[0:120, 0:160]
    rays = np.stack([(xs - 80) / 300, (ys - 60) / 320, np.ones_like(xs, float)], axis=-1)
    depth = (-5.0 / (rays @ n)).astype(np.float32)  # the plane n . X = -5, facing the camera
    normals = depth_normals(depth, K)
    inner = normals[3:-3, 3:-3].reshape(-1, 3)
    np.testing.assert_allclose(inner, np.broadcast_to(n, inner.shape), atol=1e-4)
    assert np.all(np.isnan(normals[2])) and np.all(np.isnan(normals[:, -3]))


# -- fusion -------------------------------------------------------------------------------

def _exact_views(scene, views, scale=None):
    out = []
    for k in views:
        depth = np.where(np.isfinite(scene.depths[k]), scene.depths[k], np.nan)
        depth = depth.astype(np.float32)
        if scale is not None and k in scale:
            depth = depth * np.float32(scale[k])
        out.append(ViewDepth(depth, depth_normals(depth, scene.K),
                             scene.images[k][:, :, ::-1].copy(), scene.K, scene.R[k],
                             scene.t[k]))
    return out


def test_fused_exact_depth_maps_lie_on_the_surface(orbit):
    cloud = fuse_depth_maps(_exact_views(orbit, range(4)), voxel_size=0.02)
    distances = rectangle_distances(cloud.points3d, orbit.rectangles)
    assert cloud.num_points > 50_000
    assert np.mean(distances < 1e-3 * _extent(orbit)) > 0.99


def test_a_wrong_depth_map_is_outvoted(orbit):
    """View 2's depths 5 % too far: no other view agrees, and its points are not kept (but
    for a few where the wrong depth meets another surface at an occluding edge)."""
    views = _exact_views(orbit, range(5), scale={2: 1.05})
    cloud = fuse_depth_maps(views, voxel_size=0.02, min_agree=2)
    distances = rectangle_distances(cloud.points3d, orbit.rectangles)
    assert np.mean(distances < 1e-3 * _extent(orbit)) > 0.99
    alone = fuse_depth_maps(views, voxel_size=0.02, min_agree=2,
                            check_views=[[], [], [0, 1, 3, 4], [], []])
    assert alone.num_points < 0.001 * views[2].valid_pixels


def test_voxel_thin_keeps_the_mean_of_each_voxel():
    points = np.array([[0.1, 0.1, 0.1], [0.3, 0.3, 0.3], [1.5, 0.2, 0.2]])
    colors = np.array([[0, 0, 0], [100, 200, 50], [9, 9, 9]], np.uint8)
    normals = np.array([[0, 0, 1], [0, 1, 0], [1, 0, 0]], np.float32)
    cloud = voxel_thin(points, colors, normals, voxel_size=1.0)
    order = np.argsort(cloud.points3d[:, 0])
    np.testing.assert_allclose(cloud.points3d[order], [[0.2, 0.2, 0.2], [1.5, 0.2, 0.2]])
    np.testing.assert_array_equal(cloud.colors[order], [[50, 100, 25], [9, 9, 9]])
    np.testing.assert_allclose(cloud.normals[order][0], [0, np.sqrt(0.5), np.sqrt(0.5)],
                               atol=1e-6)
    with pytest.raises(ValueError, match="voxel_size"):
        voxel_thin(points, colors, normals, 0.0)


# -- scores -------------------------------------------------------------------------------

def test_rectangle_distance_closed_form():
    rect = [Rectangle((0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (0.0, 0.0, 1.0))]
    points = [[1.0, 0.3, 0.5], [3.0, 0.0, 2.0], [1.0, -0.2, 1.5]]
    np.testing.assert_allclose(rectangle_distances(points, rect),
                               [0.3, np.sqrt(2.0), np.hypot(0.2, 0.5)])


def test_within_distance_is_exact():
    rng = np.random.default_rng(3)
    points, queries = rng.random((3000, 3)), rng.random((500, 3)) * 1.2 - 0.1
    nearest = np.linalg.norm(queries[:, None] - points[None], axis=2).min(axis=1)
    for tol in (0.01, 0.03, 0.08):
        np.testing.assert_array_equal(within_distance(queries, points, tol), nearest <= tol)


# -- the whole chain on the rendered orbit -------------------------------------------------

def test_orbit_accuracy_and_completeness(orbit, dense_orbit):
    """ETH3D's scores at 0.2 %, 0.5 % and 1 % of the scene's extent. Completeness is of the
    surface that at least three cameras see (the fusion keeps a depth that two other views
    confirm); the whole surface the cameras see is docs/dense.md's table."""
    extent = _extent(orbit)
    samples = orbit.surface_samples(min_views=3)
    scores = score_dense_cloud(dense_orbit.cloud.points3d, orbit.rectangles, samples,
                               [0.002 * extent, 0.005 * extent, 0.01 * extent])
    fine, done, coarse = scores
    assert done.accuracy >= 0.9 and done.completeness >= 0.9, done
    assert coarse.accuracy >= 0.95 and coarse.completeness >= 0.93, coarse
    assert fine.accuracy >= 0.7 and fine.completeness >= 0.75, fine


def test_orbit_normals_of_the_ground_point_up(orbit, dense_orbit):
    """Normals from the depth maps' differences: a median 11.7 degrees off on the ground,
    seen at a grazing angle (measured at 320 x 240, 2026-12-07)."""
    cloud = dense_orbit.cloud
    ground = np.abs(cloud.points3d[:, 1] - 2.0) < 0.01  # the ground at y = 2, y down
    ground &= rectangle_distances(cloud.points3d, orbit.rectangles[:36]) < 0.01
    normals = cloud.normals[ground]
    has = np.linalg.norm(normals, axis=1) > 0.5  # a point no view gave a normal has none
    up = normals[has] @ np.array([0.0, -1.0, 0.0])
    assert ground.sum() > 1000 and has.mean() > 0.8  # 88.5 %: none at depth edges
    assert np.median(up) > np.cos(np.radians(15))


def test_depth_preview_averages_the_depths_of_each_footprint_and_keeps_holes():
    """A 4 x 8 map shrunk to 2 x 4: each preview pixel the mean of its 2 x 2 block's valid
    depths, NaN where fewer than half of them have one."""
    depth = np.array([[1, 3, 2, 2, 5, np.nan, np.nan, np.nan],
                      [1, 3, 2, 2, 7, np.nan, np.nan, 9],
                      [4, 4, 6, 6, 1, 1, 8, 8],
                      [4, 4, 6, 6, 1, 1, 8, 8]], np.float32)
    preview = depth_preview(depth, width=4)
    assert preview.image_size == (8, 4) and preview.valid_pixels == 27
    np.testing.assert_allclose(preview.depth, [[2, 2, 6, np.nan], [4, 6, 1, 8]], atol=1e-6)
    assert depth_preview(depth, width=100).depth.shape == (4, 8)  # never wider than the map
    with pytest.raises(ValueError, match="shape"):
        depth_preview(np.zeros(5))


def test_densify_keeps_a_small_preview_of_each_true_depth_map(orbit, dense_orbit):
    """The result keeps previews 160 px wide, not the full maps; they follow the exact
    depths (shrunk the same way) within 1 % where both have one."""
    h, w = orbit.depths[0].shape
    assert len(dense_orbit.previews) == len(orbit.images)
    for preview, truth in zip(dense_orbit.previews, orbit.depths):
        assert preview.depth.shape == (round(h * 160 / w), 160)
        assert preview.image_size == (w, h) and preview.valid_pixels > 0.5 * w * h
        exact = depth_preview(truth).depth
        both = np.isfinite(preview.depth) & np.isfinite(exact)
        assert both.mean() > 0.5
        assert np.median(np.abs(preview.depth[both] / exact[both] - 1)) < 0.01


# -- input --------------------------------------------------------------------------------

def test_load_sparse_model_reads_a_binary_model_as_the_text_one(tmp_path, orbit):
    text = _write_scene(tmp_path / "scene", orbit)
    expected = load_sparse_model(text)
    write_colmap_binary(tmp_path / "bin", expected)
    # the binary files beside the text ones win, as in COLMAP; a colmap/ folder is looked in
    write_colmap_binary(tmp_path / "both" / "colmap", expected)
    for name in ("cameras.txt", "images.txt", "points3D.txt"):
        (tmp_path / "both" / "colmap" / name).write_text("# not read\n")
    for folder in (tmp_path / "bin", tmp_path / "both"):
        model = load_sparse_model(folder)
        assert model.names == expected.names and model.cameras == expected.cameras
        np.testing.assert_allclose(model.R, expected.R, atol=1e-12)
        np.testing.assert_allclose(model.t, expected.t, atol=1e-12)
        np.testing.assert_allclose(model.points3d, expected.points3d, atol=1e-12)


def test_load_sparse_model_refuses_a_malformed_binary_model_and_one_view(tmp_path, orbit):
    (tmp_path / "bin").mkdir()
    for name in ("cameras.bin", "images.bin", "points3D.bin"):
        (tmp_path / "bin" / name).write_bytes(b"\0" * 16)
    with pytest.raises(ColmapFormatError, match="cameras.bin"):
        load_sparse_model(tmp_path / "bin")
    one = _write_scene(tmp_path / "one", orbit, views=[0])
    with pytest.raises(DenseInputError, match="1 image") as info:
        load_sparse_model(one)
    assert info.value.reason == "one_view"
    with pytest.raises(DenseInputError, match="no COLMAP model") as info:
        load_sparse_model(tmp_path)
    assert info.value.reason == "no_model"


# -- the command --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def small_scene(tmp_path_factory):
    """Five views at 200 x 150 (the command's own run, quick)."""
    scene = render_orbit_views(5, size=(200, 150), arc_deg=40.0)
    return scene, _write_scene(tmp_path_factory.mktemp("small"), scene)


def test_dense_views_writes_the_cloud_with_normals(small_scene, tmp_path, capsys):
    scene, model = small_scene
    out = tmp_path / "out"
    code = dense_views.main([str(model), "--images", str(model.parent), "--out", str(out),
                             "--no-pyr-down"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    points, colors = read_ply(out / "dense.ply")
    normals = read_ply_normals(out / "dense.ply")
    summary = json.loads((out / "dense.json").read_text())
    assert summary["points"] == len(points) == len(normals) == len(colors)
    assert set(summary["files"]) == {"dense.ply", "dense.json", "report.html"}
    assert np.mean(rectangle_distances(points, scene.rectangles) < 0.01 * _extent(scene)) > 0.9
    assert np.median(np.linalg.norm(normals, axis=1)) == pytest.approx(1.0, abs=1e-5)
    assert f"Wrote '{out / 'dense.ply'}'" in captured.out
    # A second run replaces its own files; a file of the user's there is refused.
    assert dense_views.main([str(model), "--images", str(model.parent), "--out", str(out),
                             "--no-pyr-down", "-q"]) == 0
    (out / "dense.json").unlink()
    capsys.readouterr()
    assert dense_views.main([str(model), "--images", str(model.parent), "--out", str(out),
                             "--no-pyr-down", "-q"]) == 2
    assert "no earlier dense-views run" in capsys.readouterr().err


def _refused(capsys, argv, out, *fragments):
    code = dense_views.main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.count("\n") == 0 and err.startswith("error: "), err
    for fragment in fragments:
        assert fragment in err, err
    assert not out.exists()


def test_dense_views_bad_input_is_one_line_and_writes_nothing(small_scene, tmp_path, capsys):
    scene, model = small_scene
    out = tmp_path / "out"
    images = tmp_path / "few"
    images.mkdir()
    (images / "view00.png").write_bytes((model.parent / "view00.png").read_bytes())
    _refused(capsys, [str(model), "--images", str(images), "--out", str(out)], out,
             "4 of the model's 5 images are not in", "'view01.png' and 3 more")
    _refused(capsys, [str(model), "--images", str(tmp_path / "none"), "--out", str(out)], out,
             "image folder not found")
    one = _write_scene(tmp_path / "one", scene, views=[2])
    _refused(capsys, [str(one), "--images", str(one.parent), "--out", str(out)], out,
             "has 1 image(s)", "at least two views")
    binary = tmp_path / "binary"
    binary.mkdir()
    for name in ("cameras.bin", "images.bin", "points3D.bin"):
        (binary / name).write_bytes(b"\0" * 16)
    _refused(capsys, [str(binary), "--images", str(model.parent), "--out", str(out)], out,
             "cameras.bin", "after the last record")


def test_dense_views_mesh_without_open3d_says_how_to_get_it(small_scene, tmp_path, capsys,
                                                            monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "open3d" else real(name, *a))
    scene, model = small_scene
    out = tmp_path / "out"
    _refused(capsys, [str(model), "--images", str(model.parent), "--out", str(out), "--mesh"],
             out, "--mesh", "pip install 'scene3D[mesh]'")


def test_poisson_mesh_lies_on_the_surface(orbit, dense_orbit, tmp_path):
    o3d = pytest.importorskip("open3d")
    from scene3D.densify.mesh import poisson_mesh
    from scene3D.io.export import ply_bytes

    mesh = poisson_mesh(dense_orbit.cloud, depth=8)
    path = tmp_path / "mesh.ply"
    path.write_bytes(ply_bytes(mesh.vertices, mesh.colors, faces=mesh.faces))
    read = o3d.io.read_triangle_mesh(str(path))
    assert len(read.triangles) == len(mesh.faces) > 1000
    np.testing.assert_allclose(np.asarray(read.vertices), mesh.vertices, atol=1e-4)
    distances = rectangle_distances(mesh.vertices, orbit.rectangles)
    assert np.mean(distances < 0.01 * _extent(orbit)) > 0.85


def test_a_model_written_by_pycolmap_densifies_the_same(small_scene, tmp_path):
    pycolmap = pytest.importorskip("pycolmap")
    scene, model = small_scene
    theirs = tmp_path / "pycolmap"
    theirs.mkdir()
    pycolmap.Reconstruction(str(model)).write_text(str(theirs))
    ours = load_sparse_model(model)
    read = load_sparse_model(theirs)
    np.testing.assert_allclose(read.R, ours.R, atol=1e-9)
    np.testing.assert_allclose(read.points3d, ours.points3d, atol=1e-9)
    settings = DenseSettings(max_width=None)
    a = densify(ours, image_paths(ours, model.parent), settings).cloud
    b = densify(read, image_paths(read, model.parent), settings).cloud
    assert abs(a.num_points - b.num_points) <= 0.001 * a.num_points
    extent = _extent(scene)
    for cloud in (a, b):
        distances = rectangle_distances(cloud.points3d, scene.rectangles)
        assert np.mean(distances < 0.005 * extent) > 0.85


def test_simplify_mesh_keeps_the_bound_and_the_surface():
    """A 200 x 200 grid of a tilted plane (79,202 triangles) to at most 5,000: the vertices
    stay on the plane, the colours are the means of merged ones, and a mesh within the
    bound comes back as it is."""
    pytest.importorskip("open3d")
    from scene3D.densify.mesh import Mesh, simplify_mesh

    n = 200
    u, v = np.meshgrid(np.linspace(0, 2, n), np.linspace(0, 1, n))
    vertices = np.column_stack([u.ravel(), v.ravel(), 3 + 0.5 * u.ravel() - 0.2 * v.ravel()])
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), \
        idx[1:, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([b, d, c])])
    colors = np.tile(np.array([[200, 40, 90]], np.uint8), (n * n, 1))
    mesh = Mesh(vertices, faces, colors)
    small = simplify_mesh(mesh, 5000)
    assert 1000 < len(small.faces) <= 5000
    on_plane = small.vertices[:, 2] - (3 + 0.5 * small.vertices[:, 0] - 0.2 * small.vertices[:, 1])
    assert np.abs(on_plane).max() < 1e-9
    assert np.all(small.colors == [200, 40, 90]) and small.faces.max() < len(small.vertices)
    assert simplify_mesh(mesh, len(faces)) is mesh
