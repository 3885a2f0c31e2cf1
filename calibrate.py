#!/usr/bin/env python
"""Camera calibration from chessboard views (OpenCV with Python Blueprints, chapter 4).

Run ``python calibrate.py --help``. The work is done by ``scene3D.calibration``.
"""

from scene3D.cli import run_script
from scene3D.cli.calibrate import main

if __name__ == "__main__":
    run_script(main)
