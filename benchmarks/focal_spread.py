"""Many views without a calibration file: does the focal length's sigma cover its error?

    python benchmarks/focal_spread.py [SCENE[:FIRST-LAST] ...]

Each run reconstructs a Strecha scene's views (``$SCENE3D_DATA``, default
../shared/data), all of them or the sorted views FIRST to LAST, at 1536 px without a
calibration (the JPEGs carry no EXIF: the focal length starts from 1.2 x the longer side),
and compares the focal length found with the camera files' (``sqrt(fx fy)`` at the
working size). The sigma is shown without and with its spread over the views
(``FocalEstimate.jackknife_sigma_log``), with the error in units of each. The default
runs: windows of six and eight views of the three scenes, and the whole of fountain-P11
and castle-P19. Prints a markdown table.
"""

from __future__ import annotations

import argparse
import math
import time

DEFAULT_RUNS = ("castle-P19:0-7", "castle-P19:4-11", "castle-P19:8-15", "castle-P19:11-18",
                "fountain-P11:0-7", "fountain-P11:3-10", "Herz-Jesus-P8:0-7",
                "fountain-P11:0-5", "castle-P19:0-5", "fountain-P11", "castle-P19")


def measure(spec: str) -> str:
    """The table row of one run, ``SCENE`` or ``SCENE:FIRST-LAST``."""
    from scene3D.io.datasets import default_data_root, read_strecha_scene
    from scene3D.io.exif import read_camera_prior
    from scene3D.multiview import reconstruct_views

    name, _, window = spec.partition(":")
    scene = read_strecha_scene(default_data_root() / name)
    paths, truth = scene.paths, scene.cameras
    if window:
        first, last = map(int, window.split("-"))
        paths, truth = paths[first:last + 1], truth[first:last + 1]
    t0 = time.perf_counter()
    recon = reconstruct_views(paths, None, focal_prior=read_camera_prior(paths),
                              progress=lambda message: None)
    seconds = time.perf_counter() - t0
    focal = recon.focal
    true = math.sqrt(truth[0].K[0, 0] * truth[0].K[1, 1]) * recon.image_size[0] / \
        truth[0].image_size[0]
    error = math.log(recon.K[0, 0] / true)
    without = math.hypot(focal.adjustment_sigma_log, focal.principal_point_sigma_log)
    sigma = focal.sigma_px / focal.focal_px
    return (f"| {spec} | {int(recon.registered.sum())}/{len(paths)} | {100 * error:+.3f} | "
            f"{100 * without:.3f} | {abs(error) / without:.1f} | "
            f"{100 * focal.jackknife_sigma_log:.3f} | {100 * sigma:.3f} | "
            f"{abs(error) / sigma:.1f} | {'yes' if focal.trusted else 'no'} | {seconds:.0f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="*", default=list(DEFAULT_RUNS), metavar="SCENE[:A-B]",
                        help="a scene's folder name, with a range of its sorted views "
                             "(default: the eleven runs of the benchmarks page)")
    args = parser.parse_args()
    print("| views | registered | focal error (%) | sigma without the spread (%) | "
          "error / sigma | spread over the views (%) | sigma (%) | error / sigma | "
          "trusted | s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for spec in args.runs:
        print(measure(spec), flush=True)


if __name__ == "__main__":
    main()
