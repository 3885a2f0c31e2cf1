#!/usr/bin/env python
"""3D scene reconstruction from two photos (OpenCV with Python Blueprints, chapter 4).

Run ``python chapter4.py --help``. The work is done by the ``scene3D`` package;
this script is the book's entry point.
"""

from scene3D.cli import run_script
from scene3D.cli.chapter4 import main

if __name__ == "__main__":
    run_script(main)
