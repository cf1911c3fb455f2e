"""``python -m cpp_mujoco ...``: the ``cpp-mujoco`` command without the installed script."""

import sys

from cpp_mujoco.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
