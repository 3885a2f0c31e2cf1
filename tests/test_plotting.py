"""Matplotlib figures (scene3D.viz.plotting): laid out so that nothing covers anything."""

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from scene3D.calibration.uncertainty import UncertaintyMap
from scene3D.viz.plotting import plot_uncertainty_map


@pytest.mark.parametrize("size", [(1280, 720), (640, 480), (480, 640)])
def test_the_uncertainty_maps_title_and_colour_bar_do_not_overlap(size):
    """16:9 photos whose distortion folds back (a corner without rays): the title,
    with its 'no ray reaches' note, ran under the colour bar."""
    w, h = size
    xs, ys = np.linspace(0, w - 1, 33), np.linspace(0, h - 1, 25)
    r = np.hypot(*np.meshgrid(xs - w / 2, ys - h / 2))
    sigma = 3.0 + 12.0 * (r / r.max()) ** 4
    sigma[:3, :2] = np.nan
    fig = plot_uncertainty_map(UncertaintyMap(xs, ys, sigma, size))
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    image_ax, bar_ax = fig.axes
    title = image_ax.title.get_window_extent(renderer)
    bar = bar_ax.get_tightbbox(renderer)
    assert "no ray reaches" in image_ax.get_title()
    assert title.x1 <= bar.x0 and title.x0 >= 0
    assert title.y1 <= fig.bbox.y1
