"""examples/chapter4.ipynb runs top to bottom and gets the chapter's results right.

The notebook is executed in a fresh ipykernel (nbclient), with matplotlib's Agg backend in
the environment (the notebook's ``%matplotlib inline`` draws through Agg into PNG outputs).
Its numbers are then read from the kernel's variables and checked against the Strecha
ground truth and OpenCV's published calibration of the left*.jpg photos.
"""

from __future__ import annotations

import json

import nbformat
import numpy as np
import pytest
from nbclient import NotebookClient

from .conftest import REPO
from .test_calibration import OPENCV_LEFT_K

NOTEBOOK = REPO / "examples" / "chapter4.ipynb"

# Run in the kernel after the notebook: the variables the notebook leaves.
PROBE = """
import json
print(json.dumps({
    "rotation_error_deg": error.rotation_deg,
    "translation_error_deg": error.translation_deg,
    "num_points": result.num_points,
    "trusted": result.trusted,
    "working_width": int(scene.img1.shape[1]),
    "dense_points": dense.num_points,
    "rms_px": calibration.rms_px,
    "K": calibration.K.tolist(),
    "views": len(calibration.per_view_errors_px),
    "saved": sorted(p.name for p in written),
    "saved_camera_size": __import__("scene3D.io.colmap", fromlist=["x"]).read_colmap_text(
        "out/pair/colmap").camera(0).image_size,
}))
"""


@pytest.fixture(scope="module")
def executed(data_root, tmp_path_factory):
    """The executed notebook and the probe's values."""
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    assert all(cell.get("outputs", []) == [] for cell in notebook.cells
               if cell.cell_type == "code"), "the notebook is stored with outputs"
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SCENE3D_DATA", str(data_root))
        mp.setenv("MPLBACKEND", "Agg")
        workdir = tmp_path_factory.mktemp("notebook")  # nothing it writes lands in the repo
        client = NotebookClient(notebook, timeout=600, kernel_name="python3",
                                resources={"metadata": {"path": str(workdir)}})
        probe = nbformat.v4.new_code_cell(PROBE)
        notebook.cells.append(probe)  # run last, in the same kernel
        with client.setup_kernel():
            for index, cell in enumerate(notebook.cells):
                client.execute_cell(cell, index)  # raises CellExecutionError on an error
        notebook.cells.pop()
    text = "".join(o.get("text", "") for o in probe.outputs if o.output_type == "stream")
    return notebook, json.loads(text)


def test_every_plot_is_drawn_inline(executed):
    notebook, _ = executed
    plots = [c for c in notebook.cells if "plot" in c.metadata.get("tags", [])]
    assert len(plots) >= 4  # the book's four, then the dense and calibration figures
    for cell in plots:
        assert any("image/png" in o.get("data", {}) for o in cell.outputs), cell.source


def test_the_book_pair_agrees_with_the_ground_truth(executed):
    _, values = executed
    assert values["working_width"] == 768  # halved like the book
    assert values["rotation_error_deg"] < 0.2
    assert values["translation_error_deg"] < 0.5
    assert values["num_points"] > 500
    assert values["trusted"]
    assert values["dense_points"] >= 100 * values["num_points"]


def test_the_result_saves_itself_in_one_call(executed):
    """scene.save(folder): the PLY, cameras.json and a COLMAP model of the 3072x2048 photos."""
    _, values = executed
    assert values["saved"] == ["cameras.json", "cameras.txt", "images.txt", "point_cloud.ply",
                               "points3D.txt"]
    assert values["saved_camera_size"] == [3072, 2048]


def test_the_calibration_matches_opencvs_published_values(executed):
    _, values = executed
    assert values["views"] == 13
    assert values["rms_px"] < 0.25  # OpenCV's test expects 0.196
    np.testing.assert_allclose(values["K"], OPENCV_LEFT_K, atol=2.0)
