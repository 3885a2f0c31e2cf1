"""Command-line pieces the benchmarks share: where the data are, which scenes and pairs."""

from __future__ import annotations

import argparse
import logging
import subprocess
import sys
import time
from pathlib import Path

import cv2

from scene3D.io.datasets import BOOK_PAIR, default_data_root

REPO = Path(__file__).resolve().parents[1]

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


def quiet_run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Path:
    """Set a verdict benchmark up and return its data folder (:func:`data_folder`): one
    OpenCV thread, as every benchmark times it, and the pipeline's warnings silenced (the
    benchmark counts them in its rows)."""
    cv2.setNumThreads(1)
    logging.disable(logging.WARNING)
    return data_folder(parser, args)


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


def plain_command(folder: Path) -> list[str]:
    """The plain-OpenCV script (``plain_opencv.py``) on the book pair of ``folder``."""
    img1, img2 = (folder / name for name in BOOK_PAIR)
    return [sys.executable, str(REPO / "benchmarks" / "plain_opencv.py"), str(img1), str(img2),
            str(folder / "images" / "K.txt")]


def interleaved_times(commands: dict[str, tuple[list[str], dict[str, str]]],
                      runs: int) -> dict[str, list[float]]:
    """Wall seconds of ``runs`` runs of each named ``(command, environment)``, one after the
    other in turn so that machine noise hits all alike, after one untimed warm-up each."""
    times: dict[str, list[float]] = {name: [] for name in commands}
    for run in range(runs + 1):
        for name, (cmd, cmd_env) in commands.items():
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True, env=cmd_env)
            if run > 0:
                times[name].append(time.perf_counter() - t0)
    return times
