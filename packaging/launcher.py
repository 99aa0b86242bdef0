"""Entry point of the frozen (PyInstaller) application: the same `sketchmesh` command."""

import sys

from sketchmesh.cli import main

if __name__ == "__main__":
    sys.exit(main())
