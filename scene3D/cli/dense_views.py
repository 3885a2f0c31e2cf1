"""``scene3d dense-views``: a dense cloud (and a mesh) from a sparse model and its photos."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from ..densify.mesh import Mesh
from ..densify.pipeline import (
    DenseResult,
    DenseSettings,
    densify,
    image_paths,
    load_sparse_model,
)
from ..engines import Engine
from ..io.colmap_model import ColmapModel
from ..io.export import (
    all_or_nothing,
    atomic_write_bytes,
    atomic_write_pieces,
    colmap_image_name,
    ply_bytes,
    write_json,
    write_ply,
)
from .common import (
    ArgumentParser,
    UsageError,
    add_common_args,
    add_engine_args,
    add_size_args,
    check_report_viewer,
    exit_codes_help,
    open_engine,
    path_arg,
    positive_int,
    run_command,
)
from .outputs import FILES_KEY, prepare_output_dir, previous_outputs, recorded_files

if TYPE_CHECKING:  # the types only: dense-views imports neither at its start
    from ..multiview import MultiViewReconstruction
    from ..report.page import Html

logger = logging.getLogger("scene3D.cli")

CLOUD_FILE = "dense.ply"
MESH_FILE = "mesh.ply"
SUMMARY_FILE = "dense.json"
REPORT_FILE = "report.html"
DEFAULT_WIDTH = DenseSettings().max_width


def build_parser(prog: str = "scene3d dense-views") -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog=prog,
        description=(
            "Dense reconstruction from a sparse model: a depth map for every view by plane "
            "sweep against its best neighbours (shared sparse points, triangulation angle), "
            "fused where at least two other views agree, thinned on a voxel grid; with "
            "--mesh also a surface (screened Poisson, Open3D)."
        ),
        epilog=(
            f"Writes into --out: {CLOUD_FILE} (binary PLY: points, normals, RGB, in the "
            f"model's world frame), {SUMMARY_FILE} (points, each view's neighbours, depth "
            f"range and depth pixels, timings), {REPORT_FILE} (the model, the dense cloud in "
            "an interactive 3D view and each view's depth map, small; opens offline) and "
            f"with --mesh {MESH_FILE}. Files of those "
            "names that an earlier run wrote are replaced; a file of those names that no "
            "run wrote is refused. Bad input (no model, a malformed model, a model of "
            "one view, photos missing) stops before anything is written. "
            + exit_codes_help("no depth was confirmed by two other views") + "."
        ),
    )
    parser.add_argument("model", type=path_arg, metavar="MODEL",
                        help="a reconstruct-views output folder (its colmap/ model) or a "
                             "folder with a COLMAP model, binary (cameras.bin, images.bin, "
                             "points3D.bin: read when all three are there, as COLMAP does) "
                             "or text (cameras.txt, images.txt, points3D.txt)")
    parser.add_argument("--images", type=path_arg, required=True, metavar="DIR",
                        help="the folder the model's image names are relative to")
    parser.add_argument("--out", type=path_arg, default=Path("out/dense"), metavar="DIR",
                        help="output folder (default: out/dense)")
    add_size_args(parser, DEFAULT_WIDTH, "fountain-P11's 3072 px photos at 1536")
    parser.add_argument("--neighbours", type=positive_int, default=DenseSettings().neighbours,
                        metavar="N", help="neighbours each depth map is matched against "
                                          f"(default {DenseSettings().neighbours})")
    parser.add_argument("--mesh", action="store_true",
                        help=f"also write {MESH_FILE}, a screened Poisson surface trimmed "
                             "by density; needs the extra 'mesh' (pip install "
                             "'scene3D[mesh]', Open3D)")
    parser.add_argument("--no-report", action="store_true",
                        help=f"skip {REPORT_FILE}")
    add_engine_args(parser, "a depth map per view")
    add_common_args(parser)
    return parser


def check_out_files(out: Path, paths: list[Path], previous: list[Path]) -> None:
    """Raise :class:`UsageError` when one of ``paths`` is in ``out`` already and no earlier
    run (``previous``, its summary's files) wrote it."""
    for path in paths:
        if path.is_file() and path not in previous:
            raise UsageError(f"--out '{out}' holds '{path.name}', which no earlier "
                             "dense-views run there wrote, and the run would replace it; "
                             "move it or choose another --out")


def require_mesh_extra(option: str = "--mesh") -> None:
    """Raise :class:`UsageError` when Open3D (the mesh extra) is missing, naming ``option``."""
    from ..densify.mesh import MissingMeshExtraError, require_open3d

    try:
        require_open3d()
    except MissingMeshExtraError as exc:
        raise UsageError(f"{option}: {exc}") from None


def dense_files(out: Path, mesh: bool, report: bool = False) -> list[Path]:
    """The files a dense run writes into ``out``: the cloud, the summary, the mesh, the
    page (``dense-views``'s; ``reconstruct-views`` has its own)."""
    return [out / CLOUD_FILE, out / SUMMARY_FILE, *([out / MESH_FILE] if mesh else []),
            *([out / REPORT_FILE] if report else [])]


def dense_result(model: ColmapModel, paths: list[Path], settings: DenseSettings,
                 engine: Engine, mesh: bool) -> tuple[DenseResult, Mesh | None]:
    """The dense cloud of ``model`` from its photos ``paths`` and, with ``mesh``, its
    surface (the work of ``dense-views``, without the files)."""
    result = densify(model, paths, settings, engine=engine)
    surface = None
    if mesh:
        from ..densify.mesh import poisson_mesh

        t0 = time.perf_counter()
        surface = poisson_mesh(result.cloud)
        result.timings_s["mesh"] = time.perf_counter() - t0
    return result, surface


def reconstruction_dense(recon: MultiViewReconstruction, paths: list[Path], engine: Engine,
                         mesh: bool) -> tuple[ColmapModel, DenseResult, Mesh | None]:
    """The dense cloud (and, with ``mesh``, the surface) of ``recon``'s largest model from
    its photos ``paths`` (``reconstruct-views --dense``), with the model it was made of."""
    model = recon.colmap_model(recon.models[0])
    # colmap/images.txt has '_' for spaces: either name finds the photo.
    by_name = {**{colmap_image_name(p.name): p for p in paths}, **{p.name: p for p in paths}}
    return model, *dense_result(model, [by_name[n] for n in model.names], DenseSettings(),
                                engine, mesh)


def write_dense(out: Path, model: ColmapModel, result: DenseResult, mesh: Mesh | None,
                sources: dict[str, str], t_start: float, page: Html | None = None
                ) -> tuple[list[Path], str]:
    """Write the cloud, the mesh, ``dense.json`` and ``page`` (as report.html) into
    ``out``, all or none; the files written and the line that says what they hold.
    ``sources`` go into the summary (where the model and the images came from)."""
    prepare_output_dir(out)
    cloud = result.cloud
    summary = {
        "conventions": "world frame of the sparse model; normals face the cameras",
        **sources,
        "points": cloud.num_points, "voxel_size": result.voxel_size,
        "views": [{"name": name, "neighbours": [model.names[u] for u in result.neighbours[v]],
                   "depth_range": None if result.depth_ranges[v] is None
                   else list(result.depth_ranges[v]),
                   "depth_pixels": 0 if depth is None else depth.valid_pixels}
                  for v, (name, depth) in enumerate(zip(model.names, result.previews))],
        "mesh": None if mesh is None else {"vertices": len(mesh.vertices),
                                           "faces": len(mesh.faces)},
        "timings_s": {**result.timings_s, "total": time.perf_counter() - t_start},
        FILES_KEY: recorded_files(out, dense_files(out, mesh is not None, page is not None)),
    }
    written = []
    with all_or_nothing():
        written.append(write_ply(out / CLOUD_FILE, cloud.points3d, cloud.colors, cloud.normals))
        if mesh is not None:
            written.append(atomic_write_bytes(out / MESH_FILE, ply_bytes(
                mesh.vertices, mesh.colors, faces=mesh.faces)))
        written.append(write_json(out / SUMMARY_FILE, summary))
        if page is not None:
            written.append(atomic_write_pieces(out / REPORT_FILE, page.encoded()))
    maps = sum(depth is not None for depth in result.previews)
    line = f"{maps} depth maps, {cloud.num_points} fused points (voxel {result.voxel_size:.4g})"
    if mesh is not None:
        line += f", mesh of {len(mesh.faces)} triangles"
    return written, f"{line}, {summary['timings_s']['total']:.1f} s"


def run(args: argparse.Namespace) -> int:
    t_start = time.perf_counter()
    if args.mesh:
        require_mesh_extra()
    model = load_sparse_model(args.model)
    paths = image_paths(model, args.images)
    out = args.out
    if out.is_dir():
        check_out_files(out, dense_files(out, args.mesh, not args.no_report),
                        previous_outputs(out, SUMMARY_FILE, option="--out"))
    if not args.no_report:
        check_report_viewer()
    settings = DenseSettings(max_width=None if args.no_pyr_down else args.max_width,
                             neighbours=args.neighbours)
    with open_engine(args) as engine:
        result, mesh = dense_result(model, paths, settings, engine, args.mesh)
    page = None
    if not args.no_report:
        from ..report import DenseRun, colmap_report
        from .report import thumbnails

        page = colmap_report(model, str(args.model), thumbnails(paths, model.names),
                             DenseRun(tuple(model.names), result, mesh))
    written, line = write_dense(out, model, result, mesh,
                                {"model": str(args.model), "images": str(args.images)},
                                t_start, page)
    if not args.quiet:
        print(line)
    for path in written:
        print(f"Wrote '{path}'")
    return 0


def main(argv: list[str] | None = None, prog: str = "scene3d dense-views") -> int:
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
