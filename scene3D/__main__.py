"""``python -m scene3D``: the same as the ``scene3d`` command."""

from .cli import main, run_script

run_script(main)
