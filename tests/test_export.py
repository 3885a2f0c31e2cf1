import json

import numpy as np
import pytest
from matplotlib.figure import Figure

from scene3D.io.export import (
    all_or_nothing,
    atomic_write_bytes,
    atomic_write_pieces,
    read_ply,
    save_figure,
    write_json,
    write_ply,
    written_bytes,
)


def test_ply_round_trip_and_header(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.normal(size=(50, 3))
    colors = rng.integers(0, 256, (50, 3), dtype=np.uint8)
    path = write_ply(tmp_path / "cloud.ply", points, colors)
    data = path.read_bytes()
    header = data[: data.index(b"end_header\n")].decode()
    assert "format binary_little_endian 1.0" in header
    assert "element vertex 50" in header
    assert "property uchar red" in header
    # 15 bytes a vertex: three float32 and three uint8.
    assert len(data) == data.index(b"end_header\n") + len("end_header\n") + 50 * 15
    p, c = read_ply(path)
    np.testing.assert_allclose(p, points, rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(c, colors)


def test_writes_are_atomic_and_leave_no_temporaries(tmp_path):
    write_json(tmp_path / "a.json", {"R": np.eye(3), "n": np.int64(3), "ok": np.bool_(True)})
    assert json.loads((tmp_path / "a.json").read_text())["R"][1] == [0.0, 1.0, 0.0]
    # JSON has no NaN or infinity (Python would write them, other readers refuse them).
    write_json(tmp_path / "b.json", {"sigma": float("inf"), "v": np.array([1.0, np.nan])})
    text = (tmp_path / "b.json").read_text()
    assert "Infinity" not in text and "NaN" not in text
    assert json.loads(text) == {"sigma": None, "v": [1.0, None]}
    (tmp_path / "b.json").unlink()
    fig = Figure()
    fig.add_subplot().plot([0, 1])
    save_figure(fig, tmp_path / "f.png")
    assert (tmp_path / "f.png").read_bytes().startswith(b"\x89PNG")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "f.png"]


@pytest.mark.parametrize("kernel_copy", [True, False])
def test_pieces_write_bytes_and_whole_files_in_order(tmp_path, monkeypatch, kernel_copy):
    """A file piece is copied whole (by the kernel, or through Python where the file system
    or the platform cannot), between the byte pieces, and the target is replaced atomically."""
    import os

    if not kernel_copy:
        def refuse(*args):
            raise OSError(18, "Invalid cross-device link")
        monkeypatch.setattr(os, "copy_file_range", refuse, raising=False)
    source = tmp_path / "lib.js"
    source.write_bytes(bytes(range(256)) * 5000)  # 1.28 MB, more than one copy's chunk
    target = tmp_path / "page.html"
    target.write_bytes(b"what was there before")
    atomic_write_pieces(target, [b"<script>", source, b"</script>", b""])
    assert target.read_bytes() == b"<script>" + source.read_bytes() + b"</script>"
    assert sorted(f.name for f in tmp_path.iterdir()) == ["lib.js", "page.html"]


def test_ply_rejects_bad_shapes(tmp_path):
    with pytest.raises(ValueError, match=r"`points3d` must have shape \(N, 3\)"):
        write_ply(tmp_path / "x.ply", np.zeros((4, 2)))
    assert not (tmp_path / "x.ply").exists()


def test_a_run_that_fails_while_writing_leaves_the_earlier_results_whole(tmp_path, monkeypatch):
    """Within all_or_nothing the files of one run replace the earlier ones all or none."""
    for name in ("a.txt", "b.txt"):
        (tmp_path / name).write_text("old")
    with pytest.raises(OSError, match="No space left on device"):
        with all_or_nothing():
            atomic_write_bytes(tmp_path / "a.txt", b"new")
            assert (tmp_path / "a.txt").read_text() == "old"  # not yet
            assert written_bytes(tmp_path / "a.txt") == b"new"  # what the block wrote
            raise OSError(28, "No space left on device")  # as the next write would
    assert [(p.name, p.read_text()) for p in sorted(tmp_path.iterdir())] == \
        [("a.txt", "old"), ("b.txt", "old")]  # and no temporary file is left
    with all_or_nothing():
        atomic_write_bytes(tmp_path / "a.txt", b"new")
        write_json(tmp_path / "b.txt", {})
    assert [(p.name, p.read_text()) for p in sorted(tmp_path.iterdir())] == \
        [("a.txt", "new"), ("b.txt", "{}\n")]


def test_a_block_within_a_block_waits_for_the_outer_one(tmp_path):
    """A result's save() (its own all_or_nothing) inside a command's block: its files are
    placed when the command's block ends, and not at all when that block fails."""
    (tmp_path / "a.txt").write_text("old")
    with pytest.raises(OSError, match="No space left on device"):
        with all_or_nothing():
            with all_or_nothing():
                atomic_write_bytes(tmp_path / "a.txt", b"new")
            assert (tmp_path / "a.txt").read_text() == "old"  # the inner end placed nothing
            raise OSError(28, "No space left on device")
    assert [(p.name, p.read_text()) for p in tmp_path.iterdir()] == [("a.txt", "old")]
    with all_or_nothing():
        with all_or_nothing():
            atomic_write_bytes(tmp_path / "a.txt", b"new")
    assert (tmp_path / "a.txt").read_text() == "new"


def test_a_folder_where_a_file_goes_is_refused_before_writing(tmp_path):
    (tmp_path / "report.html").mkdir()
    (tmp_path / "a.txt").write_text("old")
    with pytest.raises(IsADirectoryError, match="a folder stands where"):
        with all_or_nothing():
            atomic_write_bytes(tmp_path / "a.txt", b"new")
            atomic_write_bytes(tmp_path / "report.html", b"<html>")
    assert (tmp_path / "a.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "report.html"]
