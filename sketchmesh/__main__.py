import sys

from sketchmesh.cli import main

sys.exit(main())
