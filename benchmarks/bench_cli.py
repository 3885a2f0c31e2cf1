"""Command-line pieces the benchmarks share: where the data are, which scenes and pairs."""

from __future__ import annotations

import argparse
from pathlib import Path

from scene3D.datasets import default_data_root

#: The shared Strecha-format scenes, easiest first.
STRECHA_SCENES = ("fountain-P11", "Herz-Jesus-P8", "castle-P19")


def add_data_arguments(parser: argparse.ArgumentParser, gaps: tuple[int, ...] = (),
                       scenes: bool = False) -> None:
    """``--data``; with ``scenes``, ``--scenes`` (default: :data:`STRECHA_SCENES`); with
    ``gaps``, ``--gaps`` (each image i paired with i + gap; default: ``gaps``)."""
    parser.add_argument("--data", type=Path, default=None,
                        help="the data folder (default: $SCENE3D_DATA)")
    if scenes:
        parser.add_argument("--scenes", nargs="+", default=list(STRECHA_SCENES),
                            help="Strecha-format scenes in the data folder (default: the three)")
    if gaps:
        parser.add_argument("--gaps", type=int, nargs="+", default=list(gaps),
                            help="pair each image i with i + gap (default: "
                                 f"{' '.join(map(str, gaps))})")


def data_folder(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Path:
    """``args.data``, else ``$SCENE3D_DATA``; a usage error when neither is set."""
    data = args.data or default_data_root()
    if data is None:
        parser.error("no data folder: pass --data or set SCENE3D_DATA")
    return data


def reconstruct_or_refusal(scene, feature: str):
    """``scene.reconstruct(feature)`` (a :class:`scene3D.SceneReconstruction3D` with its
    pair loaded), or the :class:`scene3D.errors.ReconstructionError` that refused it."""
    from scene3D.errors import ReconstructionError

    try:
        return scene.reconstruct(feature)
    except ReconstructionError as exc:
        return exc


def verdict(outcome) -> str:
    """'trusted', 'flagged' or 'refused: REASON' for :func:`reconstruct_or_refusal`'s."""
    if isinstance(outcome, Exception):
        return f"refused: {outcome.reason}"
    return "trusted" if outcome.trusted else "flagged"

