"""``python -m scene3D``: the same as the ``scene3d`` command."""

import sys

from .cli import main

sys.exit(main())
