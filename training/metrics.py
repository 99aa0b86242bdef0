"""Moved to :mod:`training.evaluation.metrics`; this alias remains only for :mod:`training.fit`.

Delete it once ``training/fit.py`` imports :mod:`training.evaluation.metrics` (that file has
another owner at the moment of the move).
"""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("training.evaluation.metrics")
