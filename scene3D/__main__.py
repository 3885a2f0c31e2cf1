"""``python -m scene3D``: the same as the ``scene3d`` command."""

from .cli import exit_process, main

exit_process(main())
