"""Moved to :mod:`training.model.losses`; this alias remains only for :mod:`training.fit`.

Delete it once ``training/fit.py`` imports :mod:`training.model.losses` (that file has another
owner at the moment of the move).
"""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("training.model.losses")
