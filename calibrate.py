#!/usr/bin/env python
"""Camera calibration from chessboard views (OpenCV with Python Blueprints, chapter 4).

Run ``python calibrate.py --help``. The work is done by ``scene3D.calibration``.
"""

import sys

from scene3D.cli.calibrate import main

if __name__ == "__main__":
    sys.exit(main())
